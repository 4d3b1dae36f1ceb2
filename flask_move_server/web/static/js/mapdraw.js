// Drawing the map view: the map image (or a metre grid without one), the zones (zonedraw.js), the plan, the goal, the spot an
// exploration heads for, the waypoints, a route (routedraw.js), the robot and the arrow being dragged
// (setting the pose: with the laser as it would lie there, laserfit.js). Pure drawing: what to draw
// is the view's state.
import {movedTo, wallShare} from "./laserfit.js";
import {drawRoute} from "./routedraw.js";
import {drawZones} from "./zonedraw.js";

export const TAP_PX = 10;  // a press that moves less than this is a tap, not a drag (no arrow drawn)

export function drawMap(v) {
  const ctx = v.ctx;
  ctx.fillStyle = "#9aa3ad";
  ctx.fillRect(0, 0, v.width, v.height);
  if (v.image && v.meta) drawImage(v, ctx);
  else drawGrid(v, ctx);
  drawZones(v, ctx);
  drawTrail(v, ctx);
  drawPlan(v, ctx);
  drawScan(v, ctx);
  if (v.exploreTarget) drawLookout(v, ctx, v.exploreTarget);
  if (v.goal) drawArrow(v, ctx, v.goal.x, v.goal.y, v.goal.yaw, "#c2185b", 16);
  drawWaypoints(v, ctx, drawRoute(v, ctx));
  if (v.drawn && v.robot) {
    const colour = v.robotStale() ? "#757575" : "#ff6d00";
    drawArrow(v, ctx, v.drawn.x, v.drawn.y, v.drawn.yaw, colour, 20);
  }
  drawDrag(v, ctx);
}

function drawImage(v, ctx) {
  ctx.imageSmoothingEnabled = v.view.scale * v.meta.resolution < 2;
  const [l, t, w, h] = v.imageRect();
  ctx.drawImage(v.image, l, t, w, h);
}

function drawGrid(v, ctx) {
  ctx.fillStyle = "#eceff1";
  ctx.fillRect(0, 0, v.width, v.height);
  ctx.strokeStyle = "#cfd8dc";
  ctx.lineWidth = 1;
  const [x0, y1] = v.toWorld(0, 0), [x1, y0] = v.toWorld(v.width, v.height);
  const step = v.view.scale < 10 ? 5 : 1;
  ctx.beginPath();
  for (let x = Math.ceil(x0 / step) * step; x <= x1; x += step) {
    const s = v.toScreen(x, 0)[0]; ctx.moveTo(s, 0); ctx.lineTo(s, v.height);
  }
  for (let y = Math.ceil(y0 / step) * step; y <= y1; y += step) {
    const s = v.toScreen(0, y)[1]; ctx.moveTo(0, s); ctx.lineTo(v.width, s);
  }
  ctx.stroke();
}

/** Where an exploration is heading, to look at what is not mapped yet: a dashed ring the goal's colour. */
function drawLookout(v, ctx, [x, y]) {
  const [sx, sy] = v.toScreen(x, y);
  ctx.save();
  for (const [colour, width, dash] of [["#fff", 6, []], ["#c2185b", 3, [6, 4]]]) {
    ctx.strokeStyle = colour;
    ctx.lineWidth = width;
    ctx.setLineDash(dash);
    ctx.beginPath(); ctx.arc(sx, sy, 15, 0, 2 * Math.PI); ctx.stroke();
  }
  ctx.restore();
}

function drawPlan(v, ctx) {
  if (v.plan.length < 2) return;
  ctx.strokeStyle = "#0050c8";
  ctx.lineWidth = 3;
  ctx.lineJoin = "round";
  ctx.beginPath();
  v.plan.forEach(([x, y], i) => { const [sx, sy] = v.toScreen(x, y); i ? ctx.lineTo(sx, sy) : ctx.moveTo(sx, sy); });
  ctx.stroke();
}

// -- waypoints: a dot with a heading tick, and a label placed where it hides nothing --

const MARKER_R = 7, TICK_PX = 17;     // the dot's radius; the heading tick reaches this far from its centre
const LABEL_FONT = "bold 14px system-ui, sans-serif", LABEL_H = 16;
// [most px wide, px from the dot]: next to the dot first, then clear of a robot standing on it, then shorter
const LABEL_TRIES = [[130, 11], [130, 24], [64, 11], [64, 24]];
/** Where the robot went: a thin line, broken where its pose jumped. */
function drawTrail(v, ctx) {
  if (v.trail.length < 2) return;
  ctx.strokeStyle = "rgba(230, 81, 0, 0.75)";
  ctx.lineWidth = 2;
  ctx.lineJoin = "round";
  ctx.beginPath();
  let open = false;
  for (const p of v.trail) {
    if (!p) { open = false; continue; }
    const [sx, sy] = v.toScreen(p[0], p[1]);
    if (open) ctx.lineTo(sx, sy); else ctx.moveTo(sx, sy);
    open = true;
  }
  ctx.stroke();
}

/** What the laser sees now: small bright dots that read on white floor, black walls and grey unknown. */
function drawScan(v, ctx) {
  const points = v.scanShown();
  if (!points.length) return;
  const size = 4, half = size / 2;
  ctx.fillStyle = "#ff1744";
  ctx.beginPath();
  for (const [x, y] of points) {
    const [sx, sy] = v.toScreen(x, y);
    ctx.rect(sx - half, sy - half, size, size);
  }
  ctx.fill();
}

/** The places, their names placed clear of `taken` (boxes already drawn: a route's badges) and of each other. */
function drawWaypoints(v, ctx, taken) {
  const spots = v.waypoints.map((w) => ({w, at: v.toScreen(w.x, w.y)}));
  for (const s of spots) drawMarker(ctx, s.at, s.w.yaw);
  taken.push(...spots.flatMap((s) => markerBoxes(s.at, s.w.yaw)));
  if (v.drawn && v.robot) taken.push(around(v.toScreen(v.drawn.x, v.drawn.y), 21));
  ctx.font = LABEL_FONT;
  ctx.textAlign = "left";
  ctx.textBaseline = "middle";
  v.labels = [];
  for (const s of spots) {
    const label = placeLabel(ctx, s, taken, v);
    if (!label) continue;  // no room anywhere: the dot alone (the list has the name)
    taken.push(label.box);
    v.labels.push(label);
    drawLabel(ctx, label);
  }
}

function drawMarker(ctx, [sx, sy], yaw) {
  const [dx, dy] = [Math.cos(yaw), -Math.sin(yaw)];
  ctx.lineCap = "round";
  for (const [colour, width] of [["#fff", 6], ["#00695c", 3]]) {
    ctx.strokeStyle = colour;
    ctx.lineWidth = width;
    ctx.beginPath(); ctx.moveTo(sx + dx * MARKER_R, sy + dy * MARKER_R); ctx.lineTo(sx + dx * TICK_PX, sy + dy * TICK_PX);
    ctx.stroke();
  }
  ctx.fillStyle = "#00695c";
  ctx.strokeStyle = "#fff";
  ctx.lineWidth = 2;
  ctx.beginPath(); ctx.arc(sx, sy, MARKER_R, 0, 2 * Math.PI); ctx.fill(); ctx.stroke();
}

/** What a marker covers: its dot and the end of its heading tick, as [left, top, right, bottom] boxes. */
function markerBoxes([sx, sy], yaw) {
  return [around([sx, sy], MARKER_R + 2), around([sx + Math.cos(yaw) * (TICK_PX - 3), sy - Math.sin(yaw) * (TICK_PX - 3)], 4)];
}

/** The first spot (above, below, right, left of the dot, near then farther) where the name, shortened as needed,
 *  overlaps nothing drawn so far and stays on the canvas; null when there is none. */
function placeLabel(ctx, {w, at: [sx, sy]}, taken, v) {
  for (const [maxWidth, gap] of LABEL_TRIES) {
    const text = shortened(ctx, w.name, maxWidth), width = ctx.measureText(text).width;
    const spots = [[sx - width / 2, sy - gap - LABEL_H], [sx - width / 2, sy + gap],
                   [sx + gap, sy - LABEL_H / 2], [sx - gap - width, sy - LABEL_H / 2]];
    for (const [x, y] of spots) {
      const box = [x - 2, y, x + width + 2, y + LABEL_H];
      const onCanvas = box[0] >= 0 && box[1] >= 0 && box[2] <= v.width && box[3] <= v.height;
      if (onCanvas && !taken.some((t) => overlaps(t, box))) return {name: w.name, text, x, y, box};
    }
  }
  return null;
}

function drawLabel(ctx, {text, x, y}) {
  ctx.lineWidth = 4;
  ctx.strokeStyle = "#fff";
  ctx.strokeText(text, x, y + LABEL_H / 2);
  ctx.fillStyle = "#002b26";
  ctx.fillText(text, x, y + LABEL_H / 2);
}

const shortenedCache = new Map();  // measuring every frame would cost a lot with many places

/** `text` as it fits in `maxWidth` px: whole, or cut (by characters, not UTF-16 halves) and ended with "…". */
function shortened(ctx, text, maxWidth) {
  const key = maxWidth + "|" + text;
  if (!shortenedCache.has(key)) {
    const chars = Array.from(text);
    let n = chars.length;
    while (n > 1 && ctx.measureText(n < chars.length ? chars.slice(0, n).join("") + "…" : text).width > maxWidth) n--;
    if (shortenedCache.size > 2000) shortenedCache.clear();
    shortenedCache.set(key, n < chars.length ? chars.slice(0, n).join("").trimEnd() + "…" : text);
  }
  return shortenedCache.get(key);
}

function around([x, y], r) { return [x - r, y - r, x + r, y + r]; }
function overlaps(a, b) { return a[0] < b[2] && b[0] < a[2] && a[1] < b[3] && b[1] < a[3]; }

function drawArrow(v, ctx, x, y, yaw, colour, size) {
  const [sx, sy] = v.toScreen(x, y);
  ctx.save();
  ctx.translate(sx, sy);
  ctx.rotate(-yaw);
  ctx.beginPath();
  ctx.moveTo(size, 0); ctx.lineTo(-size * 0.6, size * 0.6); ctx.lineTo(-size * 0.3, 0); ctx.lineTo(-size * 0.6, -size * 0.6);
  ctx.closePath();
  ctx.fillStyle = colour; ctx.fill();
  ctx.lineWidth = 2; ctx.strokeStyle = "#111"; ctx.stroke();
  ctx.restore();
}

function drawDrag(v, ctx) {
  const g = v.gesture;
  if (!g || g.kind !== "press" || v.mode === "look" || distance(g.start, g.now) < TAP_PX) return;
  const [x, y] = v.toWorld(g.start[0], g.start[1]);
  const yaw = Math.atan2(-(g.now[1] - g.start[1]), g.now[0] - g.start[0]);
  if (v.mode === "pose") drawLaserAt(v, ctx, {x, y, yaw});
  drawArrow(v, ctx, x, y, yaw, v.mode === "pose" ? "#2e7d32" : "#c2185b", 24);
}

/** Setting the pose: the laser as it would lie with the robot there, and how much of it on the walls,
 *  so the owner lines the dots up with the walls before letting go. */
function drawLaserAt(v, ctx, pose) {
  if (!v.robot || !v.scan.length || v.offline) return;
  const points = movedTo(v.scan, v.robot, pose);
  ctx.fillStyle = "#00c853";
  ctx.beginPath();
  for (const [x, y] of points) {
    const [sx, sy] = v.toScreen(x, y);
    ctx.rect(sx - 2.5, sy - 2.5, 5, 5);
  }
  ctx.fill();
  const share = wallShare(v, points);
  v.canvas.dataset.poseFit = share === null ? "" : share.toFixed(2);
  if (share === null) return;
  const [sx, sy] = v.toScreen(pose.x, pose.y);
  const text = "laser on walls " + Math.round(share * 100) + " %";
  ctx.font = "bold 14px sans-serif";
  ctx.textAlign = "center";
  ctx.textBaseline = "bottom";
  ctx.lineWidth = 4;
  ctx.strokeStyle = "#fff";
  ctx.strokeText(text, sx, sy - 30);
  ctx.fillStyle = share >= 0.7 ? "#1b5e20" : "#b00020";
  ctx.fillText(text, sx, sy - 30);
}

function distance(a, b) { return Math.hypot(a[0] - b[0], a[1] - b[1]); }
