// The Maps panel: the mode the robot is in (always shown in the top bar), start mapping,
// save the growing map, the maps with thumbnails to navigate on, rename or delete, relocalize.
// The map the stack was configured with (the demo's) is listed too ("source": "configured"):
// it can be used again, not renamed nor deleted; /mode calls it map null.
import {api, authorisedFetch, $, quietly} from "./api.js";
import {withoutApi} from "./words.js";
import {notify} from "./notice.js";

let ctx = null;
const thumbnails = new Map();  // map name + modified -> object URL, so a list refresh does not refetch

const MODE_WORDS = {idle: "idle", mapping: "mapping", navigation: "navigating"};
let configuredName = null;  // the configured map's name in GET /maps (/mode says it too, or null when shadowed)
let shownMode = null;  // the last GET /mode body or mode event shown
let modeEvents = 0;  // mode events so far: an answer to a request sent before the newest of them is older than it

function modeText(m) {
  const text = (MODE_WORDS[m.mode] || m.mode) +
    (m.mode === "navigation" ? " on " + (m.map || configuredName || "the default map") : "");
  return m.state !== "running" ? text + " · " + m.state : text;
}

/** Shows a `GET /mode` body (or `mode` event) in the top bar. */
function showMode(m) {
  const chip = $("mode");
  shownMode = m;
  chip.textContent = modeText(m);
  chip.title = withoutApi(m.message || "");  // the server words it for curl too; a tap shows it
  chip.dataset.mode = m.mode;
  chip.dataset.map = m.map || "";
  chip.dataset.state = m.state;
  if (m.state === "failed" && m.message && ctx) ctx.report(new Error(m.message), "mode");
  $("save-map").hidden = m.mode !== "mapping";
  $("start-mapping").hidden = m.mode === "mapping";
}

/** A `mode` event: the newest word on the mode, always shown. */
export function showModeEvent(m) {
  modeEvents += 1;
  showMode(m);
}

/**
 * Shows the mode body `request()` answers (and resolves to the newest body shown), unless a `mode` event came while it was under way: on a slow
 * link the answer to a switch ("starting") can come after the event "running", and is older than it.
 */
export function askMode(request) {
  const seen = modeEvents;
  return request().then((m) => {
    if (seen === modeEvents) showMode(m);
    return shownMode;  // the newest body either way
  });
}

/** Reads `GET /maps` into the list: thumbnail, name, what it is, Use, Rename, Delete. */
let mapListLoads = 0;  // the newest request wins, as for the waypoints

export async function loadMaps() {
  const mine = ++mapListLoads;
  let data;
  try { data = await api("GET", "/maps"); } catch (e) {
    if (e.status === 404) { $("maps").replaceChildren(); return; }
    throw e;
  }
  if (mine !== mapListLoads) return;
  configuredName = (data.maps.find((m) => m.source === "configured") || {}).name || null;
  if (shownMode) $("mode").textContent = modeText(shownMode);
  $("maps").replaceChildren(...data.maps.map((m) => mapRow(m, m.name === data.active)));
  $("maps").dataset.count = String(data.maps.length);
}

function mapRow(m, active) {
  const li = document.createElement("li");
  const configured = m.source === "configured";
  li.dataset.name = m.name;
  li.dataset.active = active ? "1" : "0";
  li.dataset.source = configured ? "configured" : "saved";
  const img = document.createElement("img");
  img.alt = "";
  // No picture when the robot went away meanwhile: the list is drawn again once it is back.
  thumbnail(m).then((url) => { if (url) img.src = url; }, () => {});
  const about = document.createElement("div");
  about.className = "about";
  const name = document.createElement("span");
  name.className = "name";
  name.textContent = m.name;
  const note = document.createElement("span");
  note.className = "note";
  note.textContent = mapNote(m, active, configured);
  about.append(name, note);
  const actions = document.createElement("div");
  actions.className = "actions";
  if (!active) actions.append(button("Use", "needs-live", () => useMap(m.name)));
  if (!active && !configured) {  // the map in use cannot be changed under the stack; the configured one is not ours
    actions.append(button("Rename", "quiet", () => renameMap(m.name)), button("Delete", "quiet", () => deleteMap(m.name)));
  }
  li.append(img, about, actions);
  return li;
}

/** The row's second line: what the map is, and why a button is missing. */
function mapNote(m, active, configured) {
  const places = m.waypoints === 1 ? "1 place" : (m.waypoints || 0) + " places";
  if (m.problem) return "broken: " + m.problem;
  if (configured) return places + " · set up with the robot: it cannot be renamed or deleted";
  if (active) return places + " · use another map to rename or delete it";
  return places;
}

/** An <img> cannot send the token, so thumbnails come through fetch() as object URLs. */
async function thumbnail(m) {
  const key = m.name + "@" + m.modified;
  if (!thumbnails.has(key)) {
    const response = await authorisedFetch("/maps/" + encodeURIComponent(m.name) + "/image");
    if (!response.ok) return null;
    for (const [old, url] of thumbnails) {  // the same map saved again: let its old picture go
      if (old.startsWith(m.name + "@")) { URL.revokeObjectURL(url); thumbnails.delete(old); }
    }
    thumbnails.set(key, URL.createObjectURL(await response.blob()));
  }
  return thumbnails.get(key);
}

function button(label, className, onClick) {
  const b = document.createElement("button");
  b.type = "button";
  b.textContent = label;
  b.className = className;
  b.disabled = className.includes("needs-live") && !ctx.isLive();
  b.onclick = onClick;
  return b;
}


function switchTo(body) { return quietly(askMode(() => ctx.call("POST", "/mode", body, "mode"))); }

const mapping = () => $("mode").dataset.mode === "mapping";

/** Use a map; while mapping, the map being made is not saved yet: offer to save it first, or discard it. */
async function useMap(name) {
  if (mapping()) {
    if (window.confirm("Save the map being made before using " + name + "? (Cancel: do not save it)")) {
      if (!(await saveMap(false))) return;
    } else if (!window.confirm("Use " + name + " without saving? The map being made and the places marked on it " +
                               "will be lost.")) return;
  }
  return switchTo({mode: "navigation", map: name});
}

async function renameMap(name) {
  const to = (window.prompt("New name for the map " + name + ":", name) || "").trim().normalize("NFC");
  if (!to || to === name) return;
  try {
    await api("PATCH", "/maps/" + encodeURIComponent(name), {name: to});
  } catch (e) {
    ctx.report(RENAME_WORDS[e.code] ? new Error(RENAME_WORDS[e.code](name, to)) : e, "rename");
    return;
  }
  notify("Renamed the map " + name + " to " + to);
  quietly(loadMaps());
}

const RENAME_WORDS = {
  map_exists: (name, to) => "There is a map called " + to + " already: pick another name for " + name + ".",
  map_in_use: (name) => name + " is in use: use another map first, then rename it.",
  map_configured: (name) => name + " is the robot's own map: it cannot be renamed.",
  unknown_map: (name) => "The map " + name + " is gone (deleted elsewhere?).",
};

async function deleteMap(name) {
  if (!window.confirm("Delete the map " + name + " and its places?")) return;
  await quietly(ctx.call("DELETE", "/maps/" + encodeURIComponent(name)));
  quietly(loadMaps());
}

/** Asks for the name to save a map as (Save as… and Explore): trimmed, in NFC; "" when dismissed. */
export const askMapName = (question) => (window.prompt(question) || "").trim().normalize("NFC");

/** The refusal `e` says a map called `name` exists and may be replaced (never the robot's own map: say why). */
export const replaceable = (e, name) =>
  e.code === "map_exists" && !(configuredName && name.toLowerCase() === configuredName.toLowerCase());

export const confirmReplace = (name) => window.confirm("A map called " + name + " exists. Replace it (and its places)?");

/** Asks for a name and saves the map being made (then navigates on it, unless `then` is false); true once saved. */
async function saveMap(then = true) {
  const name = askMapName("Save this map as:");
  if (!name) return false;
  let body = then ? {name, then: "navigation"} : {name};
  let saved = true;
  try {
    await api("POST", "/maps", body, 60000);
  } catch (e) {
    if (!replaceable(e, name)) { ctx.report(e, "save"); return false; }
    if (!confirmReplace(name)) return false;
    body = Object.assign(body, {overwrite: true});
    saved = await ctx.call("POST", "/maps", body, "save", 60000).then(() => true, () => false);
  }
  quietly(loadMaps());
  quietly(askMode(() => api("GET", "/mode")));
  return saved;
}

/** Wires the panel's buttons; `context`: {call, report, setGesture, isLive} from main.js. */
export function initPanels(context) {
  ctx = context;
  $("start-mapping").onclick = () => {
    if (window.confirm("Start mapping? Navigation stops and a new map grows as you drive.")) switchTo({mode: "mapping"});
  };
  $("save-map").onclick = () => saveMap();
  $("go-idle").onclick = () => {
    const question = mapping() ? "Stop mapping? The map being made is not saved: it and the places marked on it " +
      "will be lost." : "Stop mapping or navigation?";
    if (window.confirm(question)) switchTo({mode: "idle"});
  };
  $("relocalize").onclick = () => context.setGesture("pose");
}
