// The Places panel's no-go zones (docs/zones.md): draw a no-go area (tap its corners) or a wall (tap
// its points) on the map, name it, switch it on or off, delete it. The map draws them (zonedraw.js).
import {rowButton} from "./buttons.js";
import {api, $, quietly} from "./api.js";
import {notify} from "./notice.js";
import {byName, typedName} from "./words.js";

let ctx = null;  // {call, isLive, map, setGesture} from main.js
const LEAST = {keepout: 3, wall: 2};
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
  li.append(label, toggle, rowButton("Delete", "quiet", () => remove(z), ctx.isLive));
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

function begin(kind) {
  ctx.map.zoneDraft = {kind, points: []};
  $("zone-draw").hidden = false;
  $("zone-start").hidden = true;
  ctx.setGesture("zone");
  showDraft();
  $("zone-draw").scrollIntoView({block: "nearest"});  // Save and Undo in sight while the map takes the taps
}

function showDraft() {
  const d = ctx.map.zoneDraft;
  const left = LEAST[d.kind] - d.points.length;
  $("zone-hint").textContent = left > 0 ? "Tap " + (d.kind === "wall" ? "the wall's ends" : "the corners") +
    " on the map (" + left + " more)" : "Tap more, or Save";
  $("zone-save").disabled = left > 0;
  $("zone-undo").disabled = !d.points.length;
}

function end() {
  ctx.map.zoneDraft = null;
  $("zone-draw").hidden = true;
  $("zone-start").hidden = false;
  ctx.setGesture("go");
}

async function save() {
  const d = ctx.map.zoneDraft;
  const name = typedName(window.prompt("Name this " + (d.kind === "wall" ? "wall:" : "no-go area:")));
  if (!name) return;
  if (ctx.map.zones.some((z) => z.name === name) && !window.confirm("Replace the zone " + name + "?")) return;
  const points = d.points.map(([x, y]) => [Math.round(x * 100) / 100, Math.round(y * 100) / 100]);
  const body = {kind: d.kind, [d.kind === "wall" ? "line" : "polygon"]: points};
  await quietly(ctx.call("PUT", path(name), body, "zone").then(() => { notify("Saved " + name); end(); }));
  quietly(loadZones());
}

/** Wires the panel; `context`: {call, isLive, map, setGesture}. */
export function initZones(context) {
  ctx = context;
  ctx.map.onZonePoint = (x, y) => { if (ctx.map.zoneDraft) { ctx.map.zoneDraft.points.push([x, y]); showDraft(); } };
  $("zone-keepout").onclick = () => begin("keepout");
  $("zone-wall").onclick = () => begin("wall");
  $("zone-undo").onclick = () => { ctx.map.zoneDraft.points.pop(); showDraft(); };
  $("zone-cancel").onclick = end;
  $("zone-save").onclick = () => quietly(save());
}
