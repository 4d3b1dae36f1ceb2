// The Places panel and the places on the map: the list (Go, Charger, Rename, Delete), Mark here, and a
// place marked by a press on the map. The list and the map's markers are drawn from one read.
import {rowButton} from "./buttons.js";
import {api, $, quietly} from "./api.js";
import {notify} from "./notice.js";
import {byName, typedName} from "./words.js";

let ctx = null;  // {call, sendGoal, isLive, map, buzz} from main.js
const FILTER_FROM = 6;  // this many places or more: a box to find one by name

let waypointLoads = 0;  // answers can cross (a change, its event, our own reload): the newest request wins
let shownWaypoints = null;  // the list as drawn, as JSON

export async function loadWaypoints() {
  const mine = ++waypointLoads;
  const data = await api("GET", "/waypoints");
  if (mine !== waypointLoads) return;
  const shown = JSON.stringify(data.waypoints);
  if (shown === shownWaypoints) return;  // unchanged: the rows stay, so a tap landing on one is not lost
  shownWaypoints = shown;
  ctx.map.setWaypoints(data.waypoints);
  const list = $("places");
  const sorted = data.waypoints.slice().sort((a, b) => byName.compare(a.name, b.name));
  list.replaceChildren(...sorted.map(placeRow));
  list.dataset.count = String(data.waypoints.length);
  $("place-filter").hidden = data.waypoints.length < FILTER_FROM;
  filterPlaces();
}

/** Folded for finding: case and accents ignored, so "kuche" finds "Küche". */
const folded = (text) => text.normalize("NFD").replace(/\p{M}/gu, "").toLocaleLowerCase();

/** Shows the rows whose name holds what the filter box holds (all of them while it is hidden or empty). */
function filterPlaces() {
  const box = $("place-filter"), wanted = box.hidden ? "" : folded(box.value.trim());
  let matches = 0;
  for (const li of $("places").children) {
    li.hidden = Boolean(wanted) && !folded(li.dataset.name).includes(wanted);
    matches += li.hidden ? 0 : 1;
  }
  $("places").dataset.matches = String(matches);
}

function placeRow(w) {
  const li = document.createElement("li");
  li.dataset.name = w.name;
  const charger = button("\u26a1", "quiet", () => chooseCharger(w));  // narrow: names keep room
  charger.title = "Charger";
  charger.setAttribute("aria-pressed", String(!!w.dock));
  li.append(button(w.name, "go needs-live moves", () => goTo(w.name)), charger,
    button("Rename", "quiet", () => renamePlace(w)), button("Delete", "quiet", () => deletePlace(w.name)));
  return li;
}

const button = (label, className, onClick) => rowButton(label, className, onClick, ctx.isLive);

const goTo = (name) => { ctx.buzz(); return quietly(ctx.sendGoal({name})); };

/** A new waypoint under a name in use replaces that one: ask first (destructive). */
function mayReplace(name) {
  return !ctx.map.waypoints.some((w) => w.name === name) || window.confirm("Replace the place " + name + "?");
}

const placePath = (name) => "/waypoints/" + encodeURIComponent(name);

/** One PATCH: the server renames in one save, so a failure never leaves the place twice. */
async function renamePlace(w) {
  const name = typedName(window.prompt("New name for " + w.name + ":", w.name));
  if (!name || name === w.name) return;
  const overwrite = ctx.map.waypoints.some((p) => p.name === name);
  if (overwrite && !window.confirm("Replace the place " + name + "?")) return;
  await quietly(ctx.call("PATCH", placePath(w.name), {name, overwrite})
    .then(() => notify("Renamed " + w.name + " to " + name)));
  quietly(loadWaypoints());
}

async function chooseCharger(w) {
  await quietly(ctx.call("PUT", placePath(w.name), {dock: !w.dock})
    .then(() => notify(w.name + (w.dock ? " is no longer the charger" : " is the charger"))));
  quietly(loadWaypoints());
}

async function deletePlace(name) {
  if (!window.confirm("Delete the place " + name + "?")) return;
  await quietly(ctx.call("DELETE", placePath(name)).then(() => notify("Deleted " + name)));
  quietly(loadWaypoints());
}

/** Saves a place under `name` (`where`: {x, y, yaw} or {from: "current"}) and says so. */
function savePlace(name, where) {
  const said = (answer) => (answer && answer.warning ? ", but it lies in a no-go zone" : "");
  return ctx.call("PUT", placePath(name), where).then((answer) => notify("Saved " + name + said(answer)));
}

const SPOT_WORDS = {wall: "inside a wall", unknown: "not mapped yet"};

/** A spot inside a wall or in unmapped space is asked about before it is marked. */
function spotIsFine(x, y) {
  const cell = ctx.map.cellAt(x, y);
  return !SPOT_WORDS[cell] || window.confirm("This spot is " + SPOT_WORDS[cell] + ". Mark it anyway?");
}

/** A press-and-drag in Mark mode: ask for a name, then keep the place with that heading. */
export async function markPlace(x, y, yaw) {
  if (!spotIsFine(x, y)) return;
  const name = typedName(window.prompt("Name this place:"));
  if (!name || !mayReplace(name)) return;
  await quietly(savePlace(name, {x, y, yaw}));
  quietly(loadWaypoints());
}

/** Wires the panel; `context`: {call, sendGoal, isLive, map, buzz} from main.js. */
export function initPlaces(context) {
  ctx = context;
  ctx.map.onWaypoint = (name) => { if (ctx.isLive()) goTo(name); };
  $("mark-form").onsubmit = (e) => {
    e.preventDefault();
    const name = typedName($("newname").value);
    if (!name || !ctx.isLive() || !mayReplace(name)) return;
    quietly(savePlace(name, {from: "current"}).then(() => { $("newname").value = ""; return loadWaypoints(); }));
  };
  $("place-filter").oninput = filterPlaces;
}
