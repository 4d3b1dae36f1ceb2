// The map's zones (docs/zones.md): a no-go area a translucent red polygon, a wall a thick red line;
// one switched off dashed and grey. A zone being drawn: its corners and edges in the draft colour.
const ON = "rgba(198, 40, 40, 0.3)", EDGE = "#c62828", OFF = "#757575", DRAFT = "#1565c0";

export function drawZones(v, ctx) {
  for (const z of v.zones) shape(v, ctx, z.kind, z.polygon || z.line, z.enabled ? EDGE : OFF, z.enabled);
  const d = v.zoneDraft;
  if (!d) return;
  shape(v, ctx, d.kind, d.points, DRAFT, false);
  ctx.fillStyle = DRAFT;
  for (const [x, y] of d.points.map((p) => v.toScreen(p[0], p[1]))) {
    ctx.beginPath();
    ctx.arc(x, y, 6, 0, 2 * Math.PI);
    ctx.fill();
  }
}

function shape(v, ctx, kind, points, colour, filled) {
  if (!points || !points.length) return;
  const px = points.map((p) => v.toScreen(p[0], p[1]));
  ctx.save();
  ctx.beginPath();
  px.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
  if (kind === "keepout") {
    ctx.closePath();
    if (filled) { ctx.fillStyle = ON; ctx.fill(); }
  }
  if (colour === OFF) ctx.setLineDash([6, 5]);
  ctx.strokeStyle = colour;
  ctx.lineJoin = "round";
  ctx.lineWidth = kind === "wall" ? Math.max(4, 0.1 * v.view.scale) : 2;  // a wall 10 cm thick, seen at any zoom
  ctx.stroke();
  ctx.restore();
}
