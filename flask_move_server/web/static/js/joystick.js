// The joystick: up/down = linear speed, left/right = turning. While a finger holds it the
// command is sent at a steady rate (the robot's deadman stops it when the repeats end); on
// release, on pointercancel, when the page is hidden and when the window loses focus it sends
// one stop at once rather than waiting for the deadman.

const RATE_MS = 150;  // ~6.7 commands a second: well inside the default 0.5 s deadman

export class Joystick {
  constructor(pad, knob, {send, stop, maxLinear = 0.4, maxAngular = 1.5}) {
    Object.assign(this, {pad, knob, send, stop, maxLinear, maxAngular});
    this.command = null;
    this.timer = null;
    this.pointer = null;
    pad.addEventListener("pointerdown", (e) => this.press(e));
    pad.addEventListener("pointermove", (e) => { if (e.pointerId === this.pointer) this.aim(e); });
    for (const kind of ["pointerup", "pointercancel", "lostpointercapture"]) {
      pad.addEventListener(kind, (e) => { if (e.pointerId === this.pointer) this.release(); });
    }
    document.addEventListener("visibilitychange", () => { if (document.hidden) this.release(); });
    window.addEventListener("blur", () => this.release());
  }

  press(e) {
    if (this.pad.getAttribute("aria-disabled") === "true") return;
    e.preventDefault();
    this.pad.setPointerCapture(e.pointerId);
    this.pointer = e.pointerId;
    this.aim(e);
    this.tick();
    clearInterval(this.timer);
    this.timer = setInterval(() => this.tick(), RATE_MS);
    this.pad.dataset.held = "1";
  }

  aim(e) {
    const r = this.pad.getBoundingClientRect(), half = r.width / 2;
    let dx = (e.clientX - r.left - half) / half, dy = (e.clientY - r.top - half) / half;
    const len = Math.hypot(dx, dy);
    if (len > 1) { dx /= len; dy /= len; }
    this.command = {linear: round(-dy * this.maxLinear), angular: round(-dx * this.maxAngular)};
    this.knob.style.transform = "translate(" + (dx * half) + "px," + (dy * half) + "px)";
  }

  tick() { if (this.command) this.send(this.command); }

  /** Stop driving now (idempotent: only a held stick sends the stop). */
  release() {
    if (this.pointer === null) return;
    this.pointer = null;
    this.command = null;
    clearInterval(this.timer);
    this.timer = null;
    this.knob.style.transform = "";
    this.pad.dataset.held = "0";
    this.stop();
  }
}

const round = (v) => Math.round(v * 100) / 100;
