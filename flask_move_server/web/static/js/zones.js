// The Places panel's no-go zones (docs/zones.md): draw a no-go area (tap its corners) or a wall (tap
// its points) on the map, name it, switch it on or off, delete it; Edit a saved one: tap a corner to
// pick it, tap where it goes, or delete it. The map draws them (zonedraw.js).
import {rowButton} from "./buttons.js";
import {api, $, quietly} from "./api.js";
import {notify} from "./notice.js";
import {byName, typedName} from "./words.js";

let ctx = null;  // {call, isLive, map, setGesture} from main.js
const LEAST = {keepout: 3, wall: 2};
const PICK = 24;  // px: a tap this near a corner of a zone being edited picks that corner (pinch to zoom)
const path = (name) => "/zones/" + encodeURIComponent(name);

export async function loadZones() {
  const data = await api("GET", "/zones");
  ctx.map.zones = data.zones;
  const rows = data.zones.slice().sort((a, b) => byName.compare(a.name, b.name)).map(zoneRow);
  $("zones").replaceChildren(...rows);
}

function zoneRow(z) {
  const li = document.createElement("li");
  li.dataset.name = z.name;
  const what = z.kind === "wall" ? "wall" : "no-go", state = z.waiting ? "on, once the robot has left" : z.enabled ? "on" : "off";
  const label = document.createElement("span");
  label.textContent = z.name + " (" + what + ", " + state + ")";
  const toggle = rowButton("Keep out", "quiet", () => change(z, {enabled: !z.enabled}), ctx.isLive);
  toggle.title = z.enabled ? "On: tap to let the robot in today" : "Off: tap to keep the robot out";
  toggle.setAttribute("aria-pressed", String(z.enabled));
  const edit = rowButton("Edit", "quiet", () => begin(z.kind, z), ctx.isLive);
  edit.title = "Move or delete its corners on the map";
  li.append(label, toggle, edit, rowButton("Delete", "quiet", () => remove(z), ctx.isLive));
  return li;
}

async function change(z, body) {
  await quietly(ctx.call("PATCH", path(z.name), body, "zone").then(() =>
    notify(z.name + (body.enabled ? ": the robot keeps out" : ": the robot may go there"))));
  quietly(loadZones());
}

async function remove(z) {
  if (!window.confirm("Delete the zone " + z.name + "?")) return;
  await quietly(ctx.call("DELETE", path(z.name), undefined, "zone").then(() => notify("Deleted " + z.name)));
  quietly(loadZones());
}

function begin(kind, saved) {
  const points = saved ? (saved.polygon || saved.line).map((p) => p.slice()) : [];
  ctx.map.zoneDraft = {kind, points, name: saved ? saved.name : null, picked: null, before: []};
  $("zone-draw").hidden = false;
  $("zone-start").hidden = true;
  ctx.setGesture("zone");
  showDraft();
  $("zone-draw").scrollIntoView({block: "nearest"});  // Save and Undo in sight while the map takes the taps
}

function showDraft() {
  const d = ctx.map.zoneDraft;
  const left = LEAST[d.kind] - d.points.length;
  const corners = d.kind === "wall" ? "the wall's points" : "the corners";
  let hint = left > 0 ? "Tap " + (d.kind === "wall" && !d.name ? "the wall's ends" : corners) + " on the map (" +
    left + " more)" : d.name ? "Tap a corner to move it, or tap to add one; then Save" : "Tap more, or Save";
  if (d.picked !== null) hint = "Tap where corner " + (d.picked + 1) + " goes, or Delete corner";
  $("zone-hint").textContent = (d.name ? d.name + ": " : "") + hint;
  $("zone-save").disabled = left > 0;
  $("zone-undo").disabled = !d.before.length && d.picked === null;
  $("zone-corner").hidden = d.picked === null;
  $("zone-corner").disabled = d.points.length <= LEAST[d.kind];
}

function tapped(x, y) {
  const d = ctx.map.zoneDraft;
  if (!d) return;
  const near = d.name && d.picked === null ? nearestCorner(d.points, x, y) : null;  // picking: in Edit only
  if (near !== null) {
    d.picked = near;
  } else {
    remember(d);
    if (d.picked === null) d.points.push([x, y]); else d.points[d.picked] = [x, y];
    d.picked = null;
  }
  showDraft();
}

function nearestCorner(points, x, y) {
  const [tx, ty] = ctx.map.toScreen(x, y);
  let best = null, bestGap = PICK;
  points.forEach((p, i) => {
    const [px, py] = ctx.map.toScreen(p[0], p[1]);
    const gap = Math.hypot(px - tx, py - ty);
    if (gap <= bestGap) { best = i; bestGap = gap; }
  });
  return best;
}

/** Keeps the corners as they are, for Undo. */
function remember(d) {
  d.before.push(d.points.map((p) => p.slice()));
}

function deleteCorner() {
  const d = ctx.map.zoneDraft;
  remember(d);
  d.points.splice(d.picked, 1);
  d.picked = null;
  showDraft();
}

function undo() {
  const d = ctx.map.zoneDraft;
  if (d.picked !== null) d.picked = null; else if (d.before.length) d.points = d.before.pop();
  showDraft();
}

function end() {
  ctx.map.zoneDraft = null;
  $("zone-draw").hidden = true;
  $("zone-start").hidden = false;
  ctx.setGesture("go");
}

async function save() {
  const d = ctx.map.zoneDraft;
  const name = d.name || typedName(window.prompt("Name this " + (d.kind === "wall" ? "wall:" : "no-go area:")));
  if (!name) return;
  if (!d.name && ctx.map.zones.some((z) => z.name === name) && !window.confirm("Replace the zone " + name + "?")) return;
  const points = d.points.map(([x, y]) => [Math.round(x * 100) / 100, Math.round(y * 100) / 100]);
  const body = {kind: d.kind, [d.kind === "wall" ? "line" : "polygon"]: points};
  const saved = ctx.map.zones.find((z) => z.name === name);
  if (d.name && saved) body.enabled = saved.enabled;  // edited: its corners change, not whether it keeps out
  await quietly(ctx.call("PUT", path(name), body, "zone").then(() => { notify("Saved " + name); end(); }));
  quietly(loadZones());
}

/** Wires the panel; `context`: {call, isLive, map, setGesture}. */
export function initZones(context) {
  ctx = context;
  ctx.map.onZonePoint = tapped;
  $("zone-keepout").onclick = () => begin("keepout");
  $("zone-wall").onclick = () => begin("wall");
  $("zone-undo").onclick = undo;
  $("zone-corner").onclick = deleteCorner;
  $("zone-cancel").onclick = end;
  $("zone-save").onclick = () => quietly(save());
}
