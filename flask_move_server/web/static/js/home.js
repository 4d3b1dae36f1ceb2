// Home (as Valetudo's): POST /dock, saying what docking does. No charger marked: greyed, a tap says why.
import {$} from "./api.js";
const NO_DOCK = "This map has no charger marked. Drive the robot onto it, then mark that place " +
  "as the dock (PUT /waypoints/<name> with \"dock\": true).";
const LABEL = {going: "Going home", approaching: "Docking", docked: "Docked", charging: "Charging",
  undocking: "Undocking"};
let dock = null, said = null;

export function initHome({move, map, report}) {
  const home = $("home");
  map.onWaypoints = (waypoints) => {
    dock = waypoints.find((w) => w.dock) || null;
    home.setAttribute("aria-disabled", String(!dock));
    home.title = dock ? "Dock at " + dock.name : NO_DOCK;
  };
  map.onWaypoints(map.waypoints);
  home.onclick = () => dock ? move("/dock", {}).catch(() => {}) : report(new Error(NO_DOCK));
}

/** Shows `/status` `dock` or a `dock` event ({state, message, ...}, or null). */
export function showDock(d) {
  const state = d ? d.state : "";
  said = state && state !== "undocked" ? d.message : null;
  $("home").textContent = LABEL[state] || "Home";
  $("home").setAttribute("aria-pressed", String(state === "docked" || state === "charging"));
}

/** The status line's words while it docks, is docked or failed; else null. */
export const dockWords = () => said;
