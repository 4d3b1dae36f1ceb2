// The Places panel and the places on the map: the list (Go, Rename, Delete), Mark here, and a
// place marked by a press on the map. The list and the map's markers are drawn from one read.
import {api} from "./api.js";

const $ = (id) => document.getElementById(id);
const quietly = (promise) => promise.catch(() => {});
// A name as the robot keeps it: NFC, so "Küche" typed on a Mac (u + ¨) is the one typed on a phone.
const typedName = (text) => (text || "").trim().normalize("NFC");
let ctx = null;  // {call, sendGoal, isLive, map, buzz} from main.js

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
  list.replaceChildren(...data.waypoints.map(placeRow));
  list.dataset.count = String(data.waypoints.length);
}

function placeRow(w) {
  const li = document.createElement("li");
  li.dataset.name = w.name;
  li.append(button(w.name, "go needs-live moves", () => goTo(w.name)),
    button("Rename", "quiet", () => renamePlace(w)), button("Delete", "quiet", () => deletePlace(w.name)));
  return li;
}

function button(label, className, onClick) {
  const b = document.createElement("button");
  b.type = "button";
  b.textContent = label;
  b.className = className;
  b.disabled = className.includes("needs-live") && !ctx.isLive() ||
    className.includes("moves") && document.body.dataset.estop === "1";
  b.onclick = onClick;
  return b;
}

export const goTo = (name) => { ctx.buzz(); return quietly(ctx.sendGoal({name})); };

/** A new waypoint under a name in use replaces that one: ask first (destructive). */
function mayReplace(name) {
  return !ctx.map.waypoints.some((w) => w.name === name) || window.confirm("Replace the waypoint " + name + "?");
}

async function renamePlace(w) {
  const name = typedName(window.prompt("New name for " + w.name + ":", w.name));
  if (!name || name === w.name || !mayReplace(name)) return;
  await quietly(ctx.call("PUT", "/waypoints/" + encodeURIComponent(name), {x: w.x, y: w.y, yaw: w.yaw})
    .then(() => ctx.call("DELETE", "/waypoints/" + encodeURIComponent(w.name))));
  quietly(loadWaypoints());
}

async function deletePlace(name) {
  if (!window.confirm("Delete the waypoint " + name + "?")) return;
  await quietly(ctx.call("DELETE", "/waypoints/" + encodeURIComponent(name)));
  quietly(loadWaypoints());
}

/** A press-and-drag in Mark mode: ask for a name, then keep the place with that heading. */
export async function markPlace(x, y, yaw) {
  const name = typedName(window.prompt("Name this place:"));
  if (!name || !mayReplace(name)) return;
  await quietly(ctx.call("PUT", "/waypoints/" + encodeURIComponent(name), {x, y, yaw}));
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
    quietly(ctx.call("PUT", "/waypoints/" + encodeURIComponent(name), {from: "current"})
      .then(() => { $("newname").value = ""; return loadWaypoints(); }));
  };
}
