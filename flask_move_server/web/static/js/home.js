// The Home button (as Valetudo has it): sends the robot to the map's dock, the place marked as
// its charger (any name). Without one it stays on screen, greyed, and a tap says how to mark one.

const $ = (id) => document.getElementById(id);
const NO_DOCK = "This map has no charger marked. Drive the robot onto it, then mark that place " +
  "as the dock (PUT /waypoints/<name> with \"dock\": true).";

export function initHome({sendGoal, map, report}) {
  const home = $("home");
  let dock = null;
  const showDock = (waypoints) => {
    dock = waypoints.find((w) => w.dock) || null;
    home.setAttribute("aria-disabled", String(!dock));
    home.title = dock ? "Go to the dock: " + dock.name : NO_DOCK;
  };
  map.onWaypoints = showDock;
  showDock(map.waypoints);
  home.onclick = () => {
    if (!dock) { report(new Error(NO_DOCK)); return; }
    sendGoal({name: dock.name}).catch(() => {});  // late on a stalled Wi-Fi: refused by the robot, as every goal
  };
}
