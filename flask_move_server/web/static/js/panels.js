// The Maps panel: the mode the robot is in (always shown in the top bar), start mapping,
// save the growing map, the saved maps with thumbnails to navigate on, relocalize.
import {api, authorisedFetch} from "./api.js";
import {withoutApi} from "./words.js";

const $ = (id) => document.getElementById(id);
let ctx = null;
const thumbnails = new Map();  // map name + modified -> object URL, so a list refresh does not refetch

const MODE_WORDS = {idle: "idle", mapping: "mapping", navigation: "navigating"};

/** Shows a `GET /mode` body (or `mode` event) in the top bar. */
export function showMode(m) {
  const chip = $("mode");
  let text = (MODE_WORDS[m.mode] || m.mode) + (m.mode === "navigation" ? " on " + (m.map || "the default map") : "");
  if (m.state !== "running") text += " · " + m.state;
  chip.textContent = text;
  chip.title = withoutApi(m.message || "");  // the server words it for curl too; a tap shows it
  chip.dataset.mode = m.mode;
  chip.dataset.map = m.map || "";
  chip.dataset.state = m.state;
  if (m.state === "failed" && m.message && ctx) ctx.report(new Error(m.message), "mode");
  $("save-map").hidden = m.mode !== "mapping";
  $("start-mapping").hidden = m.mode === "mapping";
}

/** Reads `GET /maps` into the list: thumbnail, name, Use, Delete. */
let mapListLoads = 0;  // the newest request wins, as for the waypoints

export async function loadMaps() {
  const mine = ++mapListLoads;
  let data;
  try { data = await api("GET", "/maps"); } catch (e) {
    if (e.status === 404) { $("maps").replaceChildren(); return; }
    throw e;
  }
  if (mine !== mapListLoads) return;
  $("maps").replaceChildren(...data.maps.map((m) => mapRow(m, m.name === data.active)));
  $("maps").dataset.count = String(data.maps.length);
}

function mapRow(m, active) {
  const li = document.createElement("li");
  li.dataset.name = m.name;
  li.dataset.active = active ? "1" : "0";
  const img = document.createElement("img");
  img.alt = "";
  thumbnail(m).then((url) => { if (url) img.src = url; });
  const name = document.createElement("span");
  name.className = "name";
  name.textContent = m.name;
  const use = button("Use", "needs-live", () => useMap(m.name));
  use.hidden = active;
  li.append(img, name, use, button("Delete", "quiet", () => deleteMap(m.name)));
  return li;
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

const quietly = (promise) => promise.catch(() => {});

function switchTo(body) { return quietly(ctx.call("POST", "/mode", body, "mode").then(showMode)); }

function useMap(name) { return switchTo({mode: "navigation", map: name}); }

async function deleteMap(name) {
  if (!window.confirm("Delete the map " + name + " and its waypoints?")) return;
  await quietly(ctx.call("DELETE", "/maps/" + encodeURIComponent(name)));
  quietly(loadMaps());
}

async function saveMap() {
  const name = (window.prompt("Save this map as:") || "").trim();
  if (!name) return;
  let body = {name, then: "navigation"};
  try {
    await api("POST", "/maps", body, 60000);
  } catch (e) {
    if (e.code !== "map_exists" && e.status !== 409) { ctx.report(e, "save"); return; }
    if (!window.confirm("A map called " + name + " exists. Replace it?")) return;
    body = Object.assign(body, {overwrite: true});
    await quietly(ctx.call("POST", "/maps", body, "save", 60000));
  }
  quietly(loadMaps());
  quietly(api("GET", "/mode").then(showMode));
}

/** Wires the panel's buttons; `context`: {call, report, setGesture, isLive} from main.js. */
export function initPanels(context) {
  ctx = context;
  $("start-mapping").onclick = () => {
    if (window.confirm("Start mapping? Navigation stops and a new map grows as you drive.")) switchTo({mode: "mapping"});
  };
  $("save-map").onclick = saveMap;
  $("go-idle").onclick = () => {
    if (window.confirm("Stop mapping or navigation?")) switchTo({mode: "idle"});
  };
  $("relocalize").onclick = () => context.setGesture("pose");
}
