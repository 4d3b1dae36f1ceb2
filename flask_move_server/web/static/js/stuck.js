// The robot says it is stuck (`stuck` in /status and events), in its own words. Backing out by
// itself: amber; waiting for its owner: red, with "Back out" (POST /stuck/back_out) and "Joystick"
// (the Drive tab). A phone shows two lines of the words; a tap shows them all.
import {$} from "./api.js";

/** Shows `/status`'s `stuck` ({state, message, place, ...}, or null): the banner while it is not free. */
export function showStuck(stuck) {
  const on = !!stuck && stuck.state !== "free";
  const banner = $("stuck");
  if (banner.hidden === on || banner.dataset.state !== (on ? stuck.state : "")) banner.dataset.open = "0";
  banner.hidden = !on;
  banner.dataset.state = on ? stuck.state : "";
  document.body.dataset.stuck = on ? stuck.state : "";
  $("stuck-text").textContent = on ? stuck.message || "Stuck." : "";
  const waits = on && stuck.waiting === true;
  $("stuck-drive").hidden = !waits;
  $("stuck-back").hidden = !waits;
}

/** Wires the banner: a tap on the words shows them whole; "Back out" asks the robot to back out by
 *  itself; "Joystick" opens the Drive tab. */
export function initStuck({move, openDrive}) {
  $("stuck-text").onclick = () => { $("stuck").dataset.open = $("stuck").dataset.open === "1" ? "0" : "1"; };
  $("stuck-back").onclick = () => move("/stuck/back_out").catch(() => {});
  $("stuck-drive").onclick = openDrive;
}
