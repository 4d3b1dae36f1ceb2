// Where the robot is: after a switch to a map (or a restart) the robot sets its position to the
// map's dock wherever it stands, and says so (`localization` in the mode). The banner asks the
// owner to check it until they say it is right or set the position on the map.
import {$} from "./api.js";
let ctx = null;  // {call, setGesture} from main.js
let mode = null;  // the newest mode body: idle means no map, so no position is tracked

/** Shows a `GET /mode` body (or `mode` event): the banner while the position is assumed. */
export function showWhereabouts(m) {
  mode = m;
  const where = m.localization || {};
  const assumed = m.mode === "navigation" && m.state === "running" && where.assumed === true;
  $("whereabouts").hidden = !assumed;
  $("whereabouts").dataset.from = assumed ? where.from || "" : "";
  if (assumed) $("whereabouts-text").textContent = "Position assumed: " + (where.from || "a guess") + " — check it";
}

/** True when no map is in use (mode idle): the robot's position means nothing then. */
export const noMapInUse = () => mode !== null && mode.mode === "idle";

function confirmed(answer) {
  if (answer.localization && !answer.localization.assumed) $("whereabouts").hidden = true;
}

/** Wires "It's right" (the position stands) and "Set position" (a press on the map sets it). */
export function initWhereabouts(context) {
  ctx = context;
  $("pose-right").onclick = () => ctx.call("POST", "/pose", {confirm: true}).then(confirmed, () => {});
  $("pose-set").onclick = () => ctx.setGesture("pose");
}
