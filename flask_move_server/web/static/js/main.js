// The phone page: wires the live feed, the map, the joystick and the panels to the API.
import {api, authorisedFetch, askTokenAgain, $, quietly} from "./api.js";
import {Joystick, KeyDrive} from "./joystick.js";
import {Live} from "./live.js";
import {MapView} from "./mapview.js";
import {initPanels, askMode, showModeEvent, loadMaps} from "./panels.js";
import {initHealth} from "./health.js";
import {clearError, initNotices, notify, report} from "./notice.js";
import {StopSender} from "./stop.js";
import {withoutApi} from "./words.js";
import {initPlaces, loadWaypoints, markPlace} from "./places.js";
import {initZones, loadZones} from "./zones.js";
import {initOverlays} from "./overlays.js";
import {initDriveSpeed} from "./drivespeed.js";
import {initHome, showDock, dockWords} from "./home.js";
import {initWhereabouts, showWhereabouts, noMapInUse} from "./whereabouts.js";
import {initRoutes, loadRoutes, showPastRuns} from "./routes.js";
import {initRunStrip, loadRuns, tellRun} from "./runstrip.js";
import {initExplore, loadExploration, tellExploration} from "./explore.js";
import {showBattery} from "./battery.js";
import {initStuck, showStuck} from "./stuck.js";
import {initLaserFit, laserFitMode} from "./laserfit.js";

const map = new MapView($("map"), {overlays: [$("gesture")]});
const live = new Live();
const stopping = new StopSender($("stop"));
let mapVersion = null, mapEtag = null;

// -- errors and the status line --

/** An API call whose outcome the person sees: an error in words for people (`what` says what was
 *  tried: "goal", "pose", …), and a success clears the error of the call before. */
export const call = (method, path, body, what, timeout) => api(method, path, body, timeout).then(
  (answer) => { clearError(); return answer; },
  (e) => { report(e, what); throw e; });

// How long a motion command may take to reach the robot; later, the robot refuses it (docs/api.md,
// "Late commands"): a goal dragged during a Wi-Fi stall must not be driven when the link comes back.
const GOAL_WINDOW_S = 3, TELEOP_WINDOW_S = 1;
function within(seconds) {
  const now = live.robotNow();
  return now === null ? {} : {valid_until: Math.round((now + seconds) * 1000) / 1000};
}
/** Send the robot somewhere: `{name}` or `{x, y, yaw}`, refused by the robot if it arrives late. */
export function sendGoal(where) {
  if (latched()) {
    report({code: "estop_latched"});
    return Promise.reject(new Error("e-stop latched"));
  }
  stopping.cancel();
  return call("POST", "/goto", Object.assign({}, where, within(GOAL_WINDOW_S)), "goal");
}
/** Start a run (`/runs` with `body`), resume or skip one (`path` alone): they send the robot on, so
 *  they are refused while the e-stop is latched and end STOP's retries, as a goal does. */
function move(path, body) {
  return setOff(path, body).then((answer) => { clearError(); return answer; }, (e) => { report(e, "run"); throw e; });
}
/** As `move`, its refusals left to the caller to tell (Explore asks before replacing a saved map). */
function setOff(path, body) {
  if (latched()) return Promise.reject(Object.assign(new Error("e-stop latched"), {code: "estop_latched"}));
  stopping.cancel();
  return api("POST", path, body && Object.assign({}, body, within(GOAL_WINDOW_S)));
}
const buzz = () => { if (navigator.vibrate) navigator.vibrate(30); };  // a felt "sent" on phones that can

function showNavigation(nav) {
  const box = $("nav"), state = nav.state;
  const where = nav.target || (nav.goal ? "x " + nav.goal.x.toFixed(1) + ", y " + nav.goal.y.toFixed(1) : "the goal");
  let text = "tap a place, or drag on the map", distance = "";
  if (state === "canceling") text = "stopping…";
  else if (state === "active" || state === "pending") {
    text = "going to " + where;  // short enough for most names on a phone; a longer one is cut, never the distance
    if (nav.distance_remaining != null) distance = nav.distance_remaining.toFixed(1) + " m";
  } else if (state === "succeeded") text = "arrived at " + where;
  else if (state === "stuck") text = "stuck on the way to " + where;
  else if (state === "aborted" || state === "rejected") text = "failed: " + (nav.message ? withoutApi(nav.message) : "no way to " + where);
  else if (state === "canceled") text = document.body.dataset.run === "paused" ? "paused: the round waits" : "cancelled";
  else if (state === "idle" && nav.message) text = withoutApi(nav.message);
  $("nav-text").textContent = text;
  $("nav-text").title = text;  // cut to two lines on a phone: a tap shows it whole
  $("nav-distance").textContent = distance;
  box.dataset.state = state;
  box.dataset.target = nav.target || "";
  const going = state === "active" || state === "pending" || state === "stuck";
  $("cancel").hidden = !going;
  map.setGoal(going ? nav.goal : null);
  if (!going) map.setPlan([]);
}

function tellDock() {
  const words = dockWords();
  if (words) { $("nav-text").textContent = $("nav-text").title = words; $("nav").dataset.state = "dock"; }
}
function dockShown(d) { showDock(d); tellDock(); }

function showStatus(status) {
  if (status.navigation) showNavigation(status.navigation);
  if ("stuck" in status) showStuck(status.stuck);  // /status (the stream tells it as `stuck` events)
  if (status.teleop && status.teleop.active && status.teleop.by === "owner") {  // a goal the joystick cancelled is not news while driving
    $("nav-text").textContent = "driving with the joystick";
    $("nav").dataset.state = "teleop";
  }
  tellDock();
  const m = status.motors;
  if (m) {
    $("motors").dataset.left = String(m.left);
    $("motors").dataset.right = String(m.right);
    $("motors").textContent = "motors\n" + Number(m.left).toFixed(2) + " / " + Number(m.right).toFixed(2);
  }
}

function showEstop(estop) {
  $("estop-banner").hidden = !estop.latched;
  document.body.dataset.estop = estop.latched ? "1" : "0";
  const by = {api: "from a phone or a script", button: "by the e-stop button"}[estop.source] || estop.source;
  const at = estop.since ? " at " + new Date(estop.since).toLocaleTimeString([], {hour: "2-digit", minute: "2-digit"}) : "";
  $("estop-why").textContent = estop.latched && by ? by + at : "";  // the time as the phone shows times, not ISO
  enableControls();
}
const latched = () => document.body.dataset.estop === "1";

// -- the map, the waypoints --

let mapLoads = 0;  // only the newest of overlapping loads may draw (map events can come quickly while mapping)

/** Reads /map, then its image; the image must be of the version the metadata describes (its
 *  ETag ends in "-<version>"), else the map grew in between and both are read again. */
async function loadMap(tries = 3) {
  const mine = ++mapLoads;
  let meta;
  try { meta = await api("GET", "/map"); } catch (e) {
    if (mine !== mapLoads) return;
    if (e.status === 404) { map.setMap(null); mapVersion = mapEtag = null; }
    $("map-note").textContent = e.status !== 404 ? e.message : noMapInUse() ? "" : "waiting for the map";
    return;
  }
  const headers = mapEtag && meta.version === mapVersion ? {"If-None-Match": mapEtag} : {};
  const response = await authorisedFetch("/map/image", {headers});
  if (mine !== mapLoads) return;  // a newer load (the map gone meanwhile, say) tells what is true now
  if (response.status === 304) { $("map-note").textContent = ""; return; }
  if (!response.ok) { $("map-note").textContent = "the map image did not load"; return; }
  const etag = response.headers.get("ETag") || "";
  if (!etag.replace(/"/g, "").endsWith("-" + meta.version) && tries > 1) return loadMap(tries - 1);
  const image = await createImageBitmap(await response.blob());
  if (mine !== mapLoads) return;
  mapEtag = etag;
  mapVersion = meta.version;
  map.setMap(meta, image);
  $("map-note").textContent = "";
}


map.onPress = (mode, x, y, yaw) => {
  if (!isLive()) { flashHint("The robot is not connected: nothing was sent."); return; }
  const pose = {x: round(x), y: round(y), yaw: round(yaw)};
  buzz();
  if (mode === "go") quietly(sendGoal(pose));
  else if (mode === "pose") quietly(call("POST", "/pose", pose, "pose").then(() => { notify("Pose set"); setGesture("go"); }));
  else if (mode === "mark") markPlace(pose.x, pose.y, pose.yaw).then(() => setGesture("go"));
};
const round = (v) => Math.round(v * 1000) / 1000;
map.onTap = (mode) => {
  if (mode === "look") return;
  if (mode === "route") { flashHint("Tap a place's dot to add it to the route."); return; }
  const what = {go: "send the robot there", pose: "say where the robot is", mark: "mark a place"}[mode];
  flashHint("Press and drag to " + what + ": the drag sets the heading.");
};

let hintTimer = null;
function flashHint(text) {
  $("hint").textContent = text;
  clearTimeout(hintTimer);
  hintTimer = setTimeout(() => { $("hint").textContent = HINTS[map.mode] || ""; }, 3000);
}

const HINTS = {
  go: "",
  pose: "Press where the robot really is, drag the way it faces.",
  mark: "Press a place, drag the way it should face, then name it.",
  look: "Drag to move the map; pinch or two fingers to zoom.",
  route: "Tap places in the order to visit them.",
  zone: "Tap the corners on the map; drag to move the map.",
};

export function setGesture(mode) {
  map.mode = mode;
  $("hint").textContent = HINTS[mode] || "";
  for (const b of document.querySelectorAll("#gesture button")) b.setAttribute("aria-pressed", String(b.dataset.gesture === mode));
  $("map").dataset.gesture = mode;
}

/** The note on the map when the grey robot needs a word: lost connection, no map in use, or an old pose. */
function showStaleNote() {
  const note = !isLive() ? "robot not connected: its last known position" :
    noMapInUse() ? (map.robot ? "no map in use: the robot's last known position" : "no map in use") :
    !map.robot ? "position unknown" : map.robotStale() ? "position is old: localisation is not updating it (see Health)" : "";
  $("stale-note").textContent = note;
}

// -- live state --

const isLive = () => live.state === "live" || live.state === "polling";

function showConnection(state) {
  document.body.dataset.connection = state;
  $("conn").textContent = {live: "live", polling: "live (polling)", reconnecting: "reconnecting…",
                           unauthorised: "token needed"}[state] || state;
  map.offline = !isLive();
  showStaleNote();
  enableControls();
}

/** Controls that act on the robot work only while it is connected; those that move it, only
 *  while the e-stop is released too (greyed, so a press does not look as if it did something). */
function enableControls() {
  const off = !isLive(), still = off || latched();
  for (const el of document.querySelectorAll(".needs-live")) {
    const disabled = el.classList.contains("moves") ? still : off;
    if (el.tagName === "BUTTON") el.disabled = disabled; else el.setAttribute("aria-disabled", String(disabled));
  }
  if (still) { joystick.release(); keys.release(); }
}

/** A mode body to the where-is-the-robot banner and the stale note (the top bar shows it by itself). */
function showModes(m) {
  showWhereabouts(m);
  laserFitMode(m);
  showStaleNote();
}

/** After every (re)connect: read the whole state again, never trusting what the page held. */
function resync() {
  quietly(api("GET", "/status").then((s) => {
    map.setPose(s.pose);
    showStaleNote();
    showStatus(s);
    if (s.estop) showEstop(s.estop);
    showBattery(s.battery);
    dockShown(s.dock);
  }));
  askMode(() => api("GET", "/mode")).then(showModes, (e) => { if (e.status === 404) $("mode").textContent = "robot"; });
  quietly(loadWaypoints());
  quietly(loadZones());
  quietly(loadMap());
  quietly(loadMaps());
  quietly(loadRoutes());
  quietly(loadRuns());
  quietly(loadExploration());
}

live.onState = showConnection;
live.onConnected = resync;
live.on("pose", (p) => { map.setPose(p); showStaleNote(); });
setInterval(showStaleNote, 500);  // a pose that stops coming greys the robot without any event
live.on("status", showStatus);
live.on("estop", showEstop);
live.on("battery", showBattery);
live.on("plan", (p) => map.setPlan(p.poses));
live.on("waypoints", () => { quietly(loadWaypoints()); quietly(loadRoutes()); quietly(loadZones()); });  // they live in the waypoints file
live.on("zone", () => quietly(loadZones()));
live.on("run", (run) => {
  tellRun(run);
  if (run.trigger === "schedule") quietly(loadRoutes());  // its route's next run has moved on
});
live.on("explore", tellExploration);
live.on("stuck", showStuck);
live.on("dock", dockShown);
live.on("map", (m) => { if (m.version !== mapVersion) quietly(loadMap()); });
live.on("mode", (m) => { showModeEvent(m); showModes(m); quietly(loadMaps()); quietly(loadMap()); });

// -- controls --

// Driving: one teleop request at a time (a slow link skips a beat rather than queueing them), and
// a stop sent at once and again once a teleop still on its way has landed, which could otherwise
// reach the robot after the stop and drive it on for the deadman time.
// Each joystick command is refused by the robot if it arrives more than a second late.
let teleopInFlight = null;
function sendTeleop(command) {
  if (teleopInFlight) return;
  stopping.cancel();
  const sent = teleopInFlight = call("POST", "/teleop", Object.assign({}, command, within(TELEOP_WINDOW_S)), "teleop");
  sent.catch(() => {}).then(() => { if (teleopInFlight === sent) teleopInFlight = null; });
}
function stopDriving() {  // the stick let go: the stop is said only if it does not get through at once
  const first = stopping.send(true);
  if (teleopInFlight) teleopInFlight.catch(() => {}).then(() => first.then(() => stopping.send(true)));
}
const joystick = new Joystick($("pad"), $("knob"), {send: sendTeleop, stop: stopDriving});
const keys = new KeyDrive({send: sendTeleop, stop: stopDriving, enabled: () => isLive() && !latched()});
$("stop").onclick = () => { buzz(); joystick.release(); keys.release(); stopping.send(); };
$("cancel").onclick = () => stopping.send();
$("estop").onclick = () => quietly(call("POST", "/estop", undefined, "estop"));
$("estop-release").onclick = () => {
  if (window.confirm("Release the e-stop? The robot can move again.")) quietly(call("POST", "/estop/release"));
};
for (const b of document.querySelectorAll("#gesture button")) b.onclick = () => setGesture(b.dataset.gesture);
$("fit").onclick = () => map.fit();
$("follow").onclick = () => { map.follow = !map.follow; };
setInterval(() => $("follow").setAttribute("aria-pressed", String(map.follow)), 250);
for (const tab of document.querySelectorAll("#tabs button")) {
  tab.onclick = () => {
    for (const t of document.querySelectorAll("#tabs button")) {
      t.setAttribute("aria-selected", String(t === tab));
      $("tab-" + t.dataset.tab).hidden = t !== tab;
    }
  };
}
$("mode").onclick = () => flashHint($("mode").title || "");
$("battery").onclick = () => flashHint($("battery").title);
$("nav-text").onclick = () => flashHint($("nav-text").title || "");  // the goal line whole, when cut short  // a phone has no hover: tap the mode for its message
$("token").onclick = () => askTokenAgain().then(() => resync());
initPanels({call, report, setGesture, isLive});
initPlaces({call, sendGoal, isLive, map, buzz});
initZones({call, isLive, map, setGesture});
initHealth();
initNotices();
initOverlays({live, map});
initDriveSpeed({live, joystick, keys});
initHome({move, map, report});
initWhereabouts({call, setGesture});
initRunStrip({call, move, map, onRuns: showPastRuns});
initRoutes({call, move, isLive, map, setGesture});
initLaserFit({live, map, setGesture});
initStuck({move, openDrive: () => document.querySelector('#tabs button[data-tab="drive"]').click()});
initExplore({setOff, stop: () => { joystick.release(); keys.release(); stopping.send(); }, report, map, hint: flashHint});
setGesture("go");
showConnection("connecting");
live.start();
