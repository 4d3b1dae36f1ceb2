// Refusals in the page's own words: the server's messages are written for curl and robotctl
// ("POST /estop/release"), a person holding a phone needs to know which button to press.
// Each error code the page can meet gets a sentence; an unknown code falls back to the server's
// message with its API asides taken out.

export const byName = new Intl.Collator(undefined, {numeric: true, sensitivity: "base"});
/** A name as the robot keeps it: NFC, so "Küche" typed on a Mac (u + ¨) is the one typed on a phone. */
export const typedName = (text) => (text || "").trim().normalize("NFC");

const WORDS = {
  not_connected: () => "Not delivered: the robot is not connected.",
  no_answer: () => "The robot did not answer (weak Wi-Fi?). If the command reaches it late, the robot ignores it.",
  command_late: () => "The robot got this too late (the Wi-Fi stalled), so it did not act on it. Try again.",
  estop_latched: () => "The e-stop is on: press Release at the top first.",
  pressed: () => "The robot is pressed against something that way: pull the stick back or turn, or press Back out.",
  not_stuck: () => "The robot is not stuck any more (or it is backing out already).",
  estop_button_pressed: () => "The e-stop button on the robot is still pressed: twist it out, then Release.",
  wrong_mode: (e, what) => (e.message && withoutApi(e.message) === e.message) ? e.message : ({
    goal: "No map in use, so the robot cannot go anywhere: Maps → Use a map (or Start mapping).",
    pose: "The position can be set only when navigating on a saved map: Maps → Use a map.",
    save: "Saving needs a map being made: Maps → Start mapping first.",
    run: "Routes run only while navigating on a map: Maps → Use a map.",
    explore: "The robot cannot explore in the mode it is in: see Maps.",
  }[what] || "The robot is not in the right mode for this: see Maps."),
  move_base_unavailable: () => "The robot's navigation is not ready yet: wait until the top bar stops saying starting.",
  ros_unavailable: () => "The robot's ROS is not running yet: wait a moment (or see Health).",
  mode_switching: () => "The robot is still switching: wait until the top bar says it is running.",
  no_pose: () => "The robot does not know where it is: set its position first (the map's Pose button).",
  no_map: () => "No map in use: Maps → Use a map, or Start mapping.",
  map_in_use: () => "This map is in use: use another map (or Stop stack) first.",
  unauthorized: () => "The robot's token was not accepted: Maps → Token… to enter it again.",
  shutting_down: () => "The robot's server is stopping: try again once it is back.",
  too_many_streams: () => "Too many pages are open on this robot: close one on another phone or tab.",
  unknown_waypoint: (e) => e.message.replace(/\s*GET \/waypoints lists the known names\.?/, ""),
  run_conflict: (e) => /^Run \d+ \(/.test(e.message) ?  // "Run 3 (rounds) is running: cancel it first"
    "Another route is running: press Cancel on its strip at the top first, or wait until it ends." :
    "The route has moved on meanwhile (it ended, or is no longer paused): see its strip.",
  explore_conflict: (e) => (EXPLORE_REFUSALS.find(([pattern]) => pattern.test(e.message)) || [0, withoutApi(e.message)])[1],
  modes_off: () => "This robot's navigation is started outside its server, so the page cannot switch it to mapping.",
  unknown_run: () => "That run of a route is no longer kept on the robot.",
  unknown_route: () => "That route is gone (deleted on another phone?).",
  bad_route: (e) => withoutApi(e.message).replace(/Field '(\w+)'/g, (all, f) => ROUTE_FIELDS[f] || f)
    .replace(/\bwaypoints?\b/g, (w) => w.replace("waypoint", "place")),
  waypoint_in_use: (e) => unquoted(e.message)
    .replace(/^The waypoint (.*) is used by (.*): change or delete (it|them) first\.?$/,
      (all, place, routes, it) => "The place " + place + " is a stop of " + routes + ": take it out (Routes → Edit) " +
        "or delete " + (it === "it" ? "the route" : "those routes") + " first."),
};

// Why an exploration cannot start, by the server's sentence (explore/explorer.py, web/explore.py).
const EXPLORE_REFUSALS = [
  [/^Run \d+ /, "A route is running: press Cancel on its strip at the top first, or wait until it ends."],
  [/already exploring/, "The robot is exploring already: its strip at the top says how far it got (Stop ends it)."],
  [/does not run the navigation stack/, "This robot's mapping is started outside its server, so it cannot explore " +
    "by itself: start mapping on the robot and drive it with the joystick."],
  [/does not explore/, "This robot's server cannot explore by itself: Start mapping and drive it with the joystick."],
  [/shutting down/, "The robot's server is stopping: try again once it is back."],
];

// A route's fields as the Routes panel labels them (the server names the JSON field).
const ROUTE_FIELDS = {waypoints: "The stops", loops: "Loops", dwell: "Wait at each place", on_failure: "If a place " +
  "cannot be reached", schedule: "Runs by itself at"};

/** A server sentence with its JSON-quoted names shown as typed: "sofa", not \"sofa\". */
const unquoted = (text) => text.replace(/"((?:[^"\\]|\\.)*)"/g, (all, name) => name.replace(/\\(.)/g, "$1"));

/** The sentence to show for `error` (an ApiError, or any Error); `what` says what was tried. */
export function words(error, what) {
  const say = WORDS[error.code];
  return say ? say(error, what) : withoutApi(error.message || String(error));
}

/** A server sentence without its asides for curl: "(POST /pose sets it)", ": POST /mode {…}". */
export function withoutApi(text) {
  return text
    .replace(/\s*\([^()]*(?:\b(?:GET|POST|PUT|PATCH|DELETE) \/|robotctl)[^()]*\)/g, "")
    .replace(/[:;,]?\s*(?:\b(?:GET|POST|PUT|PATCH|DELETE) \/\S*|robotctl [^.;]*)[^.;]*(?=[.;]|$)/g, "")
    .replace(/\s+\./g, ".").trim();
}
