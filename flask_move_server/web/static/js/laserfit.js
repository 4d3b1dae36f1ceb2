// Does the laser lie on the map's walls where the robot is shown? The page has the laser's echoes
// (`scan` events) and the map image, so it looks itself, at no cost to the robot (AMCL's covariance
// is its belief, not evidence: issue 33). While navigating, a yellow banner says so when for two
// seconds under half the dots lie within a cell of a wall, with "Set position". The Pose gesture
// shows the laser at the dragged pose, and its share on the walls, to line the dots up.
import {$} from "./api.js";

const WARN_BELOW = 0.5;   // the share of dots on walls under which the position is clearly wrong
const CLEAR_AT = 0.7;     // ... and at or over which the warning goes again
const LOOKS = 6;          // scans looked at (3 a second: two seconds): each under WARN_BELOW to warn
const MIN_POINTS = 20;    // fewer dots tell nothing (an open hall, a laser mostly out of range)
const TURNING = 0.5;      // rad/s: while the robot turns faster, the dots smear: not looked at

/** The share (0-1) of `points` ([[x, y], ...] in the map frame) within a cell of a wall of `map`'s image,
 *  or null when too few lie on the map to tell. */
export function wallShare(map, points) {
  const m = map.meta;
  if (!m || !map.image) return null;
  let seen = 0, on = 0;
  for (const [x, y] of points) {
    const here = map.cellAt(x, y);
    if (here === null || here === "unknown") continue;
    seen += 1;
    if (nearWall(map, x, y, m.resolution)) on += 1;
  }
  return seen >= MIN_POINTS ? on / seen : null;
}

function nearWall(map, x, y, step) {
  for (const dx of [-step, 0, step]) {
    for (const dy of [-step, 0, step]) {
      if (map.cellAt(x + dx, y + dy) === "wall") return true;
    }
  }
  return false;
}

/** The laser's `points` as they would lie with the robot at `to` instead of `from` ({x, y, yaw}). */
export function movedTo(points, from, to) {
  const turn = to.yaw - from.yaw, c = Math.cos(turn), s = Math.sin(turn);
  return points.map(([x, y]) => {
    const dx = x - from.x, dy = y - from.y;
    return [to.x + c * dx - s * dy, to.y + s * dx + c * dy];
  });
}

const shares = [];  // the last LOOKS scans' shares on the walls
let mode = null;  // the newest mode body: only navigation on a saved map is looked at

/** The mode now (a `GET /mode` body, read at each (re)connect): a new one starts the looks afresh. */
export function laserFitMode(m) {
  mode = m;
  shares.length = 0;
  $("laserfit").hidden = true;
}

/** Follows the scans and warns while they miss the map; `setGesture` starts the Pose gesture. */
export function initLaserFit({live, map, setGesture}) {
  let last = null;
  const show = (warn, share) => {
    $("laserfit").hidden = !warn;
    if (warn) $("laserfit-text").textContent = "The laser does not match the map here (" +
      Math.round(share * 100) + " % on walls): set the robot's position.";
  };
  live.on("mode", laserFitMode);
  live.on("pose", (p) => {  // how fast it turns, from one pose to the next
    const now = performance.now();
    if (!p) { last = null; return; }
    const turned = last ? Math.abs(Math.atan2(Math.sin(p.yaw - last.yaw), Math.cos(p.yaw - last.yaw))) : 0;
    last = {yaw: p.yaw, at: now, rate: last && now > last.at ? turned / ((now - last.at) / 1000) : 0};
  });
  live.on("scan", (scan) => {
    const navigating = mode && mode.mode === "navigation" && mode.state === "running";
    if (!navigating || !last || last.rate > TURNING) return;
    const share = wallShare(map, scan.points || []);
    if (share === null) return;
    shares.push(share);
    if (shares.length > LOOKS) shares.shift();
    if (!$("laserfit").hidden) {
      if (share >= CLEAR_AT) show(false);
      else show(true, share);
    } else if (shares.length === LOOKS && shares.every((v) => v < WARN_BELOW)) {
      show(true, Math.max(...shares));
    }
    map.canvas.dataset.laserFit = share.toFixed(2);
  });
  $("laserfit-set").onclick = () => setGesture("pose");
}
