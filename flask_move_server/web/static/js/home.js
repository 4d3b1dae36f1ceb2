// The Home button (as Valetudo has it): sends the robot to the `dock` waypoint of the map in
// use. Without a place named dock it stays on screen, greyed, and a tap says how to make one.

const $ = (id) => document.getElementById(id);
const DOCK = "dock";
const NO_DOCK = "This map has no place named dock. Drive the robot to where it charges, then in " +
  "Places name that spot dock.";

export function initHome({sendGoal, map, report}) {
  const home = $("home");
  const showDock = (waypoints) => {
    const has = waypoints.some((w) => w.name === DOCK);
    home.setAttribute("aria-disabled", String(!has));
    home.title = has ? "Go to the dock" : NO_DOCK;
  };
  map.onWaypoints = showDock;
  showDock(map.waypoints);
  home.onclick = () => {
    if (home.getAttribute("aria-disabled") === "true") { report(new Error(NO_DOCK)); return; }
    sendGoal({name: DOCK}).catch(() => {});  // late on a stalled Wi-Fi: refused by the robot, as every goal
  };
}
