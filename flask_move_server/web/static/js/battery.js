// The battery in the top bar, from `/status` `battery` and `battery` events: "87 %" beside a
// battery drawn as full as it is, a bolt while it charges; hidden while the robot has no reading
// (a robot without a fuel gauge). A robot that tells only its voltage shows "12.1 V". Greyed
// when the reading is old (its publisher stopped); a tap says it in words ("Battery 62 %, charging").
import {$} from "./api.js";
const OLD_S = 30;  // the robot tells the reading again once it is this old (reporter.BATTERY_OLD)
const LOW = 20;  // %: at or below, the chip turns red

/** Shows a `/status` battery (or a `battery` event): `{percentage, voltage, charging, age}` or null. */
export function showBattery(b) {
  const chip = $("battery");
  const known = !!b && (b.percentage != null || b.voltage != null);
  chip.hidden = !known;
  if (!known) { chip.dataset.level = ""; return; }
  const percent = b.percentage != null ? Math.round(b.percentage) : null;
  const amount = percent != null ? percent + "\u202f%" : b.voltage.toFixed(1) + "\u202fV";
  const old = b.age >= OLD_S;
  $("battery-text").textContent = amount;
  $("battery-fill").style.width = (percent != null ? percent : 0) + "%";  // a voltage alone: an outline, no guess
  chip.dataset.level = percent == null ? "" : percent <= LOW ? "low" : "ok";
  chip.dataset.charging = b.charging ? "1" : "0";
  chip.dataset.old = old ? "1" : "0";
  const words = "Battery " + amount + (b.charging ? ", charging" : "") +
    (old ? " (last heard " + Math.round(b.age) + " s ago)" : "");
  chip.title = words;
  chip.setAttribute("aria-label", words);
}
