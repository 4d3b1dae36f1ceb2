// The Routes panel: the map's routes (their stops, loops, the times they run by themselves) with
// Run, Edit and Delete, New route (routeedit.js), and the last few runs with how each ended; an
// interrupted one (the robot's server stopped under it) can be resumed.
import {rowButton} from "./buttons.js";
import {api, $, quietly} from "./api.js";
import {notify} from "./notice.js";
import {clock, runName, runResult} from "./runwords.js";
import {tellRun} from "./runstrip.js";
import {editRoute, initRouteEditor} from "./routeedit.js";
import {byName} from "./words.js";

const PAST = 5;  // past runs listed
let ctx = null;  // {call, move, isLive, map, setGesture} from main.js
let routes = [];
let routeLoads = 0, shownRoutes = null;

/** Reads GET /routes into the list (the newest answer wins; an unchanged list keeps its rows). */
export async function loadRoutes() {
  const mine = ++routeLoads;
  const data = await api("GET", "/routes");
  if (mine !== routeLoads) return;
  const shown = JSON.stringify(data.routes);
  if (shown === shownRoutes) return;
  shownRoutes = shown;
  routes = data.routes.slice().sort((a, b) => byName.compare(a.name, b.name));
  $("routes").replaceChildren(...routes.map(routeRow));
}

function routeRow(r) {
  const li = document.createElement("li");
  li.dataset.name = r.name;
  const actions = document.createElement("div");
  actions.className = "actions";
  actions.append(button("Run", "needs-live moves", () => run(r.name)),
    button("Edit", "quiet", () => editRoute(r)), button("Delete", "quiet", () => deleteRoute(r.name)));
  li.append(about(r.name, routeNote(r)), actions);
  return li;
}

/** "sofa → dock → office", then "twice · waits 10 s · at 21:30, mon-fri 09:00 · next Mon 09:00". */
function routeNote(r) {
  const loops = r.loops === 0 ? "until stopped" : r.loops === 1 ? "once" : r.loops === 2 ? "twice" : r.loops + " times";
  const wait = r.dwell ? "waits " + r.dwell + " s" : "";
  const at = r.schedule.length ? "at " + r.schedule.join(", ") : "";
  const next = r.next_run ? "next " + nextRun(r.next_run) : "";
  return r.waypoints.join(" → ") + "\n" + [loops, wait, at, next].filter(Boolean).join(" · ");
}

/** "today 21:30", "Mon 09:00": on the 24-hour clock the timetable is written in. */
function nextRun(iso) {
  const at = new Date(iso);
  const time = at.toLocaleTimeString([], {hour: "2-digit", minute: "2-digit", hourCycle: "h23"});
  return (at.toDateString() === new Date().toDateString() ? "today" : at.toLocaleDateString([], {weekday: "short"})) +
    " " + time;
}

function about(title, note) {
  const box = document.createElement("div");
  box.className = "about";
  const name = document.createElement("span");
  name.className = "name";
  name.textContent = title;
  const line = document.createElement("span");
  line.className = "note";
  line.textContent = note;
  box.append(name, line);
  return box;
}

const button = (label, className, onClick) => rowButton(label, className, onClick, ctx.isLive);

const run = (name) => quietly(ctx.move("/runs", {route: name}).then((answer) => tellRun(answer.run)));

async function deleteRoute(name) {
  if (!window.confirm("Delete the route " + name + "? Its places stay.")) return;
  await quietly(ctx.call("DELETE", "/routes/" + encodeURIComponent(name), undefined, "route")
    .then(() => notify("Deleted the route " + name)));
  quietly(loadRoutes());
}

/** The last few runs that are over, newest first, each with how it ended. */
export function showPastRuns(runs) {
  const past = runs.filter((r) => r.state !== "running" && r.state !== "paused").slice(0, PAST);
  $("runs").replaceChildren(...past.map((r) => {
    const li = document.createElement("li");
    li.dataset.id = String(r.id);
    li.dataset.state = r.state;
    li.append(about(runName(r) + " · " + clock(r.started), runResult(r)));
    if (r.state === "interrupted") {
      li.append(button("Resume", "needs-live moves", () => quietly(ctx.move("/runs/" + r.id + "/resume").then(tellRun))));
    }
    return li;
  }));
}

/** Wires the panel; `context`: {call, move(path, body), isLive, map, setGesture} from main.js. */
export function initRoutes(context) {
  ctx = context;
  initRouteEditor({call: ctx.call, map: ctx.map, setGesture: ctx.setGesture,
                   routeNames: () => routes.map((r) => r.name), saved: () => quietly(loadRoutes())});
  $("new-route").onclick = () => editRoute(null);
}
