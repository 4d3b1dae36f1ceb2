// The run strip: while a route runs (or is paused), a line under the goal line with its name,
// "2 of 3: office", the loop, and Pause or Resume, Skip, Cancel; its progress drawn on the map.
// Fed by `run` events and, after every (re)connect, by GET /runs; the runs it knows go on to the
// Routes panel's list of past runs. A run this page saw under way says how it ended, over the map.
import {api, $, quietly} from "./api.js";
import {notify, report} from "./notice.js";
import {runLoop, runName, runResult, runStop} from "./runwords.js";

const ACTIVE = ["running", "paused"];
const KEPT = 20;  // runs held for the panel's list (it shows the last few)
let ctx = null;  // {call, move, map, onRuns} from main.js
let runs = [];  // newest first
let shownId = null;  // the active run on the strip

/** Reads the robot's runs afresh (after a reconnect): the strip and the list show what is true now. */
export async function loadRuns() {
  const data = await api("GET", "/runs");
  runs = data.runs.slice(0, KEPT);
  show();
}

/** A run as the robot told it (a `run` event, or the answer to a command). */
export function tellRun(run) {
  runs = [run, ...runs.filter((r) => r.id !== run.id)].sort((a, b) => b.id - a.id).slice(0, KEPT);
  show();
}

function show() {
  const active = runs.find((r) => ACTIVE.includes(r.state)) || null;
  if (shownId !== null && (!active || active.id !== shownId)) announceEnd(runs.find((r) => r.id === shownId));
  shownId = active ? active.id : null;
  showStrip(active);
  ctx.map.runStops = active ? stopsOf(active) : null;
  ctx.onRuns(runs);
}

function showStrip(run) {
  const strip = $("run");
  strip.hidden = !run;
  strip.dataset.state = run ? run.state : "";
  strip.dataset.id = run ? String(run.id) : "";
  document.body.dataset.run = run ? run.state : "";  // the goal line's Cancel gives way to the strip's
  if (!run) return;
  $("run-name").textContent = runName(run);
  $("run-loop").textContent = runLoop(run);
  $("run-where").textContent = (run.state === "paused" ? "paused · " : "") + runStop(run);
  $("run-pause").hidden = run.state !== "running";
  $("run-resume").hidden = run.state !== "paused";
}

/** The run's stops in this loop: done (visited or missed), the current one, those to come. */
function stopsOf(run) {
  const missed = new Set(run.missed.filter((m) => m.loop === run.loop).map((m) => m.name));
  return run.waypoints.map((name, i) => ({
    name, state: i === run.index ? "current" : i > run.index ? "todo" : missed.has(name) ? "missed" : "visited"}));
}

/** The run on the strip is over: how it ended, as a note (an error when it failed). */
function announceEnd(run) {
  if (!run || ACTIVE.includes(run.state)) return;
  const text = runName(run) + ": " + runResult(run);
  const alarming = run.state === "failed" || run.state === "interrupted" || /^The e-stop/.test(run.message || "");
  if (alarming) report(new Error(text));  // red, like any refusal: not the green of "done"
  else notify(text);
}


/** Pause and Cancel stop the robot; Resume and Skip send it on, so they go as motion commands. */
function act(action) {
  if (shownId === null) return;
  const path = "/runs/" + shownId + "/" + action;
  const sent = action === "resume" || action === "skip" ? ctx.move(path) : ctx.call("POST", path, undefined, "run");
  quietly(sent.then(tellRun));
}

/** Wires the strip; `context`: {call, move(path, body), map, onRuns(runs)} from main.js. */
export function initRunStrip(context) {
  ctx = context;
  for (const action of ["pause", "resume", "skip", "cancel"]) $("run-" + action).onclick = () => act(action);
}
