// Exploring: the Maps panel's Explore button (it asks for the map's name as Save as… does) and the
// strip under the goal line that follows an exploration in plain words, with Stop; the spot the robot
// is driving to is drawn on the map. Fed by `explore` events and, after every (re)connect, GET /explore.
// How one ended stays on the strip (OK closes it), but only for an exploration this page saw under way.
import {api, $} from "./api.js";
import {clearError} from "./notice.js";
import {askMapName, confirmReplace, replaceable} from "./panels.js";
import {endedBy, sentence} from "./runwords.js";
import {withoutApi} from "./words.js";

const ACTIVE = ["starting", "exploring", "returning", "saving"];
let ctx = null;  // {setOff, stop, report, map} from main.js
let shown = null;  // the exploration on the strip
let seen = null;  // the key of the one this page saw under way: only its end is told
let receivedAt = 0;  // performance.now() when `shown` came: its clock goes on from there

const keyOf = (e) => e.save_as + "@" + e.started;
const plural = (n, one, many) => n + " " + (n === 1 ? one : many);
const capital = (text) => text.charAt(0).toUpperCase() + text.slice(1);
const firstSentence = (text) => (text || "").split(". ")[0];  // the why; the rest is advice, said below in the page's words

/** "2:10", "1:02:10": how long it has been going. */
export function clock(seconds) {
  const s = Math.floor(seconds || 0), h = Math.floor(s / 3600), m = Math.floor(s / 60) % 60;
  const mmss = String(s % 60).padStart(2, "0");
  return h ? h + ":" + String(m).padStart(2, "0") + ":" + mmss : m + ":" + mmss;
}

/** The strip's two lines for exploration `e`: what it does, and how far it got. */
function exploreWords(e, elapsed = e.elapsed) {
  const mapped = Math.round(e.known_m2 || 0) + " m² mapped";
  const away = e.unreachable ? plural(e.unreachable, "place", "places") + " out of reach" : "";
  const progress = (...parts) => parts.filter(Boolean).join(" · ");
  switch (e.state) {
    case "starting": return ["Exploring: starting to map", clock(elapsed)];
    case "exploring": return ["Exploring: " + (e.frontiers ? plural(e.frontiers, "place", "places") + " left to look at" :
      "looking for places not seen yet"), progress(mapped, away, clock(elapsed))];
    case "returning": return ["Coming back to where it started", progress(mapped, clock(elapsed))];
    case "saving": return ["Saving the map as " + e.save_as, progress(mapped, clock(elapsed))];
    case "done": return ["Done: saved " + (e.map || e.save_as),
      progress(e.then === "idle" ? "The robot is idle now" : "Now navigating on it", mapped + " in " + clock(elapsed))];
    case "failed": return ["Exploring failed", withoutApi(e.message || "The robot gave no reason.")];
    case "stuck": return ["Stuck: the robot could not move", withoutApi(e.message || "")];
    case "canceled": return ["Exploring stopped", capital(endedBy(e.message) || sentence(firstSentence(e.message))) +
      ". The map so far is not saved (Maps → Save as…)"];
    default: return [e.state, withoutApi(e.message || "")];
  }
}

/** Reads the exploration afresh (after a reconnect): the strip shows what is true now. */
export async function loadExploration() {
  const data = await api("GET", "/explore");
  if (data.exploration) tellExploration(data.exploration);
  else show(null);
}

/** An exploration as the robot told it (an `explore` event, or the answer to Explore). */
export function tellExploration(e) {
  receivedAt = performance.now();
  if (ACTIVE.includes(e.state)) seen = keyOf(e);
  show(ACTIVE.includes(e.state) || keyOf(e) === seen ? e : null);
}

function show(e) {
  shown = e;
  const active = !!e && ACTIVE.includes(e.state);
  $("explore").hidden = !e;
  $("explore").dataset.state = e ? e.state : "";
  document.body.dataset.explore = active ? "active" : "";  // the goal line's Cancel gives way to the strip's Stop
  $("explore-stop").hidden = !active;
  $("explore-close").hidden = active;
  ctx.map.exploreTarget = active && e.target ? e.target : null;
  tick();
}

/** The words, and the clock going on between events while the exploration is under way. */
function tick() {
  if (!shown) return;
  const going = ACTIVE.includes(shown.state) ? (performance.now() - receivedAt) / 1000 : 0;
  const [title, detail] = exploreWords(shown, (shown.elapsed || 0) + going);
  $("explore-title").textContent = title;
  $("explore-text").title = title + ": " + detail;  // cut short on a phone: a tap shows it whole
  $("explore-detail").textContent = detail;
}

/** Explore: the name to save the map as, then POST /explore (a saved name: asks to replace it). */
async function explore() {
  const name = askMapName("Explore: the robot drives by itself to map every room it can reach, comes back to where " +
                          "it started, and saves the map. Save it as:");
  if (!name) return;
  try {
    return started(await ctx.setOff("/explore", {save_as: name}));
  } catch (e) {
    if (!replaceable(e, name)) { ctx.report(e, "explore"); return; }
  }
  if (!confirmReplace(name)) return;
  try {
    started(await ctx.setOff("/explore", {save_as: name, overwrite: true}));
  } catch (e) { ctx.report(e, "explore"); }
}

function started(answer) {
  clearError();
  tellExploration(answer.exploration);
}

/** Wires the button and the strip; `context`: {setOff(path, body), stop(), report, map} from main.js. */
export function initExplore(context) {
  ctx = context;
  $("explore-start").onclick = () => explore();
  $("explore-stop").onclick = () => ctx.stop();
  $("explore-close").onclick = () => { seen = null; show(null); };
  $("explore-text").onclick = () => ctx.hint($("explore-text").title);
  setInterval(() => { if (shown && ACTIVE.includes(shown.state)) tick(); }, 1000);
}
