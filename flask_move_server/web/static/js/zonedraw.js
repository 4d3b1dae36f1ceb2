// The map's zones (docs/zones.md): a no-go area a translucent red polygon, a wall a thick red line;
// one switched off dashed and grey. A zone being drawn or edited: its corners and edges in the draft
// colour (the saved shape of one being edited is not drawn under it), the corner picked ringed.
const ON = "rgba(198, 40, 40, 0.3)", EDGE = "#c62828", OFF = "#757575", DRAFT = "#1565c0";

export function drawZones(v, ctx) {
  const d = v.zoneDraft;
  for (const z of v.zones) {
    if (d && z.name === d.name) continue;
    shape(v, ctx, z.kind, z.polygon || z.line, z.enabled ? EDGE : OFF, z.enabled);
  }
  if (!d) return;
  shape(v, ctx, d.kind, d.points, DRAFT, false);
  ctx.fillStyle = DRAFT;
  ctx.strokeStyle = DRAFT;
  ctx.lineWidth = 3;
  d.points.map((p) => v.toScreen(p[0], p[1])).forEach(([x, y], i) => {
    ctx.beginPath();
    ctx.arc(x, y, 6, 0, 2 * Math.PI);
    ctx.fill();
    if (i !== d.picked) return;
    ctx.beginPath();
    ctx.arc(x, y, 14, 0, 2 * Math.PI);
    ctx.stroke();
  });
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
