// A route on the map: a line through its stops in order and a numbered badge at each (a place
// visited twice shows both numbers: "1,3"). While a run goes, the stops done are greyed and
// ticked, the current one is orange, a missed one red and crossed. Pure drawing: the stops are
// the view's `routeShown()`, [{name, state: todo | current | visited | missed}], in order.

const COLOURS = {todo: "#6a1b9a", current: "#e65100", visited: "#757575", missed: "#b00020"};
const MARKS = {visited: "✓", missed: "✗"};
const BADGE_R = 10, BADGE_GAP = 19;  // the badge's radius; its centre this far from the place's dot, behind its heading
const BADGE_FONT = "bold 13px system-ui, sans-serif";
const RANK = {current: 0, missed: 1, todo: 2, visited: 3};  // a place visited twice shows its most pressing state

/** Draws the route shown, if any; returns the boxes its badges cover, for the labels to avoid. */
export function drawRoute(v, ctx) {
  const stops = v.routeShown();
  if (!stops.length) return [];
  const where = new Map(v.waypoints.map((w) => [w.name, w]));
  const known = stops.map((s, i) => ({...s, n: i + 1, w: where.get(s.name)})).filter((s) => s.w);
  drawLine(v, ctx, known.map((s) => v.toScreen(s.w.x, s.w.y)));
  return groups(known).map((g) => drawBadge(v, ctx, g));
}

function drawLine(v, ctx, points) {
  if (points.length < 2) return;
  ctx.save();
  ctx.lineJoin = "round";
  ctx.setLineDash([10, 6]);
  for (const [colour, width] of [["#fff", 6], [COLOURS.todo, 3]]) {
    ctx.strokeStyle = colour;
    ctx.lineWidth = width;
    ctx.beginPath();
    points.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
    ctx.stroke();
  }
  ctx.restore();
}

/** The stops at each place: one badge per place, its numbers joined and its most pressing state. */
function groups(stops) {
  const byName = new Map();
  for (const s of stops) {
    const g = byName.get(s.name) || {w: s.w, numbers: [], state: s.state};
    g.numbers.push(s.n);
    if (RANK[s.state] < RANK[g.state]) g.state = s.state;
    byName.set(s.name, g);
  }
  return [...byName.values()];
}

function drawBadge(v, ctx, {w, numbers, state}) {
  const [px, py] = v.toScreen(w.x, w.y);
  const [x, y] = [px - Math.cos(w.yaw) * BADGE_GAP, py + Math.sin(w.yaw) * BADGE_GAP];  // opposite the heading tick
  const text = MARKS[state] || numbers.join(",");
  ctx.font = BADGE_FONT;
  const half = Math.max(BADGE_R, ctx.measureText(text).width / 2 + 5);
  pill(ctx, x, y, half);
  ctx.fillStyle = COLOURS[state] || COLOURS.todo;
  ctx.fill();
  ctx.lineWidth = state === "current" ? 3 : 2;
  ctx.strokeStyle = state === "current" ? "#000" : "#fff";
  ctx.stroke();
  ctx.fillStyle = "#fff";
  ctx.textAlign = "center";
  ctx.textBaseline = "middle";
  ctx.fillText(text, x, y + 1);
  return [x - half - 2, y - BADGE_R - 2, x + half + 2, y + BADGE_R + 2];
}

/** A pill (roundRect is newer than some phones' Safari): half-circles at the ends of a bar. */
function pill(ctx, x, y, half) {
  const r = BADGE_R, straight = half - r;
  ctx.beginPath();
  ctx.arc(x + straight, y, r, -Math.PI / 2, Math.PI / 2);
  ctx.arc(x - straight, y, r, Math.PI / 2, 3 * Math.PI / 2);
  ctx.closePath();
}
