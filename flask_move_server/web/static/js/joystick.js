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

const KEYS = {ArrowUp: [1, 0], KeyW: [1, 0], ArrowDown: [-1, 0], KeyS: [-1, 0],
              ArrowLeft: [0, 1], KeyA: [0, 1], ArrowRight: [0, -1], KeyD: [0, -1]};

/** The keyboard on a desktop: arrows or WASD held drive like the joystick pushed to its edge,
 *  with the same steady repeats and the same stop when the last key is let go or focus is lost. */
export class KeyDrive {
  constructor({send, stop, enabled, maxLinear = 0.3, maxAngular = 1.2}) {
    Object.assign(this, {send, stop, enabled, maxLinear, maxAngular});
    this.held = new Set();
    this.timer = null;
    window.addEventListener("keydown", (e) => this.down(e));
    window.addEventListener("keyup", (e) => this.up(e));
    window.addEventListener("blur", () => this.release());
    document.addEventListener("visibilitychange", () => { if (document.hidden) this.release(); });
  }

  down(e) {
    if (!KEYS[e.code] || e.target.tagName === "INPUT" || !this.enabled()) return;
    e.preventDefault();
    if (this.held.has(e.code)) return;  // the key's own auto-repeat: our timer sets the pace
    this.held.add(e.code);
    this.tick();
    if (!this.timer) this.timer = setInterval(() => this.tick(), RATE_MS);
  }

  up(e) {
    if (!this.held.delete(e.code)) return;
    if (this.held.size === 0) this.release();
  }

  tick() {
    let forward = 0, turn = 0;
    for (const code of this.held) { forward += KEYS[code][0]; turn += KEYS[code][1]; }
    this.send({linear: round(Math.sign(forward) * this.maxLinear), angular: round(Math.sign(turn) * this.maxAngular)});
  }

  release() {
    if (!this.timer) return;
    this.held.clear();
    clearInterval(this.timer);
    this.timer = null;
    this.stop();
  }
}
