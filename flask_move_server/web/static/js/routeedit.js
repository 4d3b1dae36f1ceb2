// Making or changing a route: the places tapped on the map (or in the list under the stops) in the
// order to visit them, drawn on the map as they are added; how many loops, the wait at each place,
// what a place that cannot be reached does, and the times it runs by itself. Save is one PUT; a
// route given a new name is saved under it first, then the old one deleted (never lost half-way).
import {notify, report} from "./notice.js";
import {$} from "./api.js";
import {byName, typedName} from "./words.js";

const routePath = (name) => "/routes/" + encodeURIComponent(name);
let ctx = null;  // {call, map, setGesture, routeNames(), saved()} from routes.js
let draft = null;  // {original: the name it had, or null for a new route; stops: [names]}

/** Opens the editor on `route` (GET /routes' shape), or on a new one when null. */
export function editRoute(route) {
  draft = {original: route ? route.name : null, stops: route ? [...route.waypoints] : []};
  $("route-name").value = route ? route.name : "";
  $("route-loops").value = String(route ? route.loops : 1);
  $("route-dwell").value = String(route ? route.dwell : 0);
  $("route-failure").value = route ? route.on_failure : "stop";
  $("route-schedule").value = route ? route.schedule.join(", ") : "";
  $("route-editor").hidden = false;
  $("route-list").hidden = true;
  showPicker();
  showStops();
  ctx.setGesture("route");
}

const editing = () => draft !== null;

function close() {
  draft = null;
  ctx.map.draft = null;
  $("route-editor").hidden = true;
  $("route-list").hidden = false;
  ctx.setGesture("go");
}

/** A place tapped on the map or in the list: the route's next stop. */
function addStop(name) {
  if (!draft) return;
  draft.stops.push(name);
  showStops();
}

function showStops() {
  ctx.map.draft = draft.stops.map((name) => ({name, state: "todo"}));
  $("route-stops").replaceChildren(...draft.stops.map((name, i) => stopChip(name, i)));
}

function stopChip(name, i) {
  const li = document.createElement("li");
  li.dataset.name = name;
  const b = button((i + 1) + " " + name + " ✕", () => { draft.stops.splice(i, 1); showStops(); });
  b.setAttribute("aria-label", "Take stop " + (i + 1) + ", " + name + ", out of the route");
  li.append(b);
  return li;
}

/** The places to add, in name order, as "+ kitchen" buttons. */
function showPicker() {
  if (!draft) return;
  const names = ctx.map.waypoints.map((w) => w.name).sort(byName.compare);
  $("route-picker").replaceChildren(...names.map((name) => {
    const b = button("+ " + name, () => addStop(name));
    b.dataset.name = name;
    return b;
  }));
}

function button(label, onClick) {
  const b = document.createElement("button");
  b.type = "button";
  b.className = "quiet";
  b.textContent = label;
  b.onclick = onClick;
  return b;
}

/** "21:30, mon,wed 09:00; sat 10:15" -> ["21:30", "mon,wed 09:00", "sat 10:15"]: a comma after a time
 *  ends an entry, one inside the days does not. */
export const times = (text) => text.replace(/(\d:\d\d)\s*,/g, "$1;").split(/[;\n]/).map((t) => t.trim()).filter(Boolean);
const number = (text, otherwise) => (text.trim() === "" ? otherwise : Number(text));

function body() {
  return {waypoints: draft.stops, loops: number($("route-loops").value, 1), dwell: number($("route-dwell").value, 0),
          on_failure: $("route-failure").value, schedule: times($("route-schedule").value)};
}

/** What stops a save before it is sent, in words; "" when nothing does. */
function missing(name) {
  if (!name) return "Give the route a name first.";
  if (!draft.stops.length) return "Tap the places on the map in the order to visit them (or add them from the list).";
  return "";
}

async function save(event) {
  event.preventDefault();
  const name = typedName($("route-name").value), original = draft.original;
  if (missing(name)) { report(new Error(missing(name))); return; }
  if (name !== original && ctx.routeNames().includes(name) && !window.confirm("Replace the route " + name + "?")) return;
  try { await ctx.call("PUT", routePath(name), body(), "route"); } catch (e) { return; }
  if (original && original !== name) await ctx.call("DELETE", routePath(original), undefined, "route").catch(() => {});
  notify("Saved the route " + name);
  close();
  ctx.saved();
}

/** Wires the editor; `context`: {call, map, setGesture, routeNames(), saved()}. */
export function initRouteEditor(context) {
  ctx = context;
  ctx.map.onRouteStop = addStop;
  ctx.map.canvas.addEventListener("waypoints", showPicker);
  $("route-editor").onsubmit = save;
  $("route-discard").onclick = close;
}
