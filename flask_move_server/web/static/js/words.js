// Refusals in the page's own words: the server's messages are written for curl and robotctl
// ("POST /estop/release"), a person holding a phone needs to know which button to press.
// Each error code the page can meet gets a sentence; an unknown code falls back to the server's
// message with its API asides taken out.

const WORDS = {
  not_connected: () => "Not delivered: the robot is not connected.",
  no_answer: () => "The robot did not answer (weak Wi-Fi?). If the command reaches it late, the robot ignores it.",
  command_late: () => "The robot got this too late (the Wi-Fi stalled), so it did not act on it. Try again.",
  estop_latched: () => "The e-stop is on: press Release at the top first.",
  estop_button_pressed: () => "The e-stop button on the robot is still pressed: twist it out, then Release.",
  wrong_mode: (e, what) => (e.message && withoutApi(e.message) === e.message) ? e.message : ({
    goal: "No map in use, so the robot cannot go anywhere: Maps → Use a map (or Start mapping).",
    pose: "The position can be set only when navigating on a saved map: Maps → Use a map.",
    save: "Saving needs a map being made: Maps → Start mapping first.",
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
};

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
