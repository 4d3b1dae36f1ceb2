// How fast the joystick and the keys drive: a speed setting (a share of the robot's own limits,
// which /status tells as teleop.max_linear and max_angular, and which the server clamps to
// anyway) and a Slow mode for tight spots, both kept on this device.
import {$} from "./api.js";

const SPEED_KEY = "robotDriveSpeed";  // percent of the robot's limit
const SLOW_KEY = "robotDriveSlow";
const SLOW_PERCENT = 25;
const KEY_SHARE = 0.75;  // the keys drive at this share of the joystick's full deflection

export function initDriveSpeed({live, joystick, keys}) {
  const range = $("speed-range"), slow = $("slow");
  const limits = {linear: joystick.maxLinear, angular: joystick.maxAngular};
  range.value = String(clampPercent(Number(localStorage.getItem(SPEED_KEY) || 100)));
  slow.setAttribute("aria-pressed", String(localStorage.getItem(SLOW_KEY) === "1"));

  function apply() {
    const slowOn = slow.getAttribute("aria-pressed") === "true";
    const share = (slowOn ? SLOW_PERCENT : Number(range.value)) / 100;
    joystick.maxLinear = limits.linear * share;
    joystick.maxAngular = limits.angular * share;
    keys.maxLinear = joystick.maxLinear * KEY_SHARE;
    keys.maxAngular = joystick.maxAngular * KEY_SHARE;
    range.disabled = slowOn;
    $("speed-text").textContent = joystick.maxLinear.toFixed(2) + " m/s\nmax " + limits.linear.toFixed(2);
    $("speed").dataset.linear = joystick.maxLinear.toFixed(3);
  }
  range.oninput = () => { localStorage.setItem(SPEED_KEY, range.value); apply(); };
  slow.onclick = () => {
    const on = slow.getAttribute("aria-pressed") !== "true";
    slow.setAttribute("aria-pressed", String(on));
    localStorage.setItem(SLOW_KEY, on ? "1" : "0");
    apply();
  };
  live.on("status", (s) => {
    const t = s.teleop;
    if (!t || !(t.max_linear > 0) || !(t.max_angular > 0)) return;
    if (t.max_linear === limits.linear && t.max_angular === limits.angular) return;
    limits.linear = t.max_linear;
    limits.angular = t.max_angular;
    apply();
  });
  apply();
}

function clampPercent(value) { return Number.isFinite(value) ? Math.max(10, Math.min(100, value)) : 100; }
