// What the robot sees and where it went, drawn over the map (as Vizanti and ROSboard show them):
// the laser scan of `scan` events (the server sends them only while a page reads its events) and
// the trail of the poses this page was told, cleared when the map in use changes (at the switch's
// start and again once it runs, so no pose of the old map's frame is joined to the new one). A button over
// the map hides the scan; the choice is kept on this device.
import {$} from "./api.js";

const SHOW_SCAN_KEY = "robotShowScan";

export function initOverlays({live, map}) {
  const toggle = $("scan-toggle");
  const show = (on) => {
    map.showScan = on;
    toggle.setAttribute("aria-pressed", String(on));
  };
  show(localStorage.getItem(SHOW_SCAN_KEY) !== "0");
  toggle.onclick = () => {
    show(!map.showScan);
    localStorage.setItem(SHOW_SCAN_KEY, map.showScan ? "1" : "0");
  };
  live.on("scan", (scan) => map.setScan(scan.points));
  let shownMap;  // the mode, map and its state the trail was drawn in: a switch ends with "running"
  live.on("mode", (m) => {
    const now = m.mode + "/" + (m.map || "") + "/" + m.state;
    if (shownMap !== undefined && now !== shownMap) map.clearTrail();
    shownMap = now;
  });
}
