// Runs of routes in the page's words: where a run is ("2 of 3: office · loop 1 of 2") and how one
// ended ("done", "missed office: no path", "stopped: STOP was pressed"). The server's messages are
// written for scripts (they name the endpoint that ended the run); these say what a person did.
import {withoutApi} from "./words.js";

/** The route's name, or what an unnamed run (a script's list of places) is. */
export const runName = (run) => run.route || "a list of places";

/** Where the run is in its loop: "2 of 3: office". */
export const runStop = (run) => (run.index + 1) + " of " + run.waypoints.length + ": " + run.waypoints[run.index];

/** Which loop, when the route repeats: "loop 2 of 3", "loop 4, until stopped"; "" for a route gone once. */
export function runLoop(run) {
  if (run.loops === 1) return "";
  return "loop " + run.loop + (run.loops ? " of " + run.loops : ", until stopped");
}

// Who ended a run, from the server's sentence (robot.py, missions/executor.py).
const ENDED_BY = [
  [/^Stopped \(POST \/stop\)/, () => "STOP was pressed"],
  [/^The e-stop was engaged \(its button\)/, () => "the e-stop button was pressed"],
  [/^The e-stop was engaged/, () => "the e-stop was pressed"],
  [/^A goal to a pose \(POST \/goto\)/, () => "the robot was sent elsewhere"],
  [/^A goal to (.*) \(POST \/goto\)/, (m) => "the robot was sent to " + m[1]],
  [/^Driven by joystick/, () => "the robot was driven with the joystick"],
  [/^The robot switched to (\w+)/, (m) => "the robot switched to " + m[1]],
];

/** How a run that is over ended, in a few words. */
export function runResult(run) {
  const said = sentence(run.message);
  if (run.state === "succeeded") return run.missed.length ? "done, but " + missedText(run.missed) : "done";
  if (run.state === "failed") return run.missed.length ? missedText(run.missed.slice(-1)) : "failed: " + said;
  if (run.state === "canceled") return /^Canceled \(POST \/runs/.test(run.message || "") ? "cancelled" : stoppedBy(run);
  if (run.state === "skipped") {
    return "skipped at " + clock(run.started) + ": " + sentence((run.message || "").replace(/^Not run at its scheduled time:\s*/, ""));
  }
  if (run.state === "interrupted") return "interrupted: the robot's server stopped under it";
  return run.state;
}

function stoppedBy(run) {
  return "stopped: " + (endedBy(run.message) || sentence(run.message));
}

/** Who ended something the robot was doing (a run, an exploration), from the server's sentence: "STOP was
 *  pressed"; null when the sentence says no one the page knows. */
export function endedBy(message) {
  for (const [pattern, say] of ENDED_BY) {
    const m = pattern.exec(message || "");
    if (m) return say(m);
  }
  return null;
}

/** "missed office: no path" for one; "missed 2: office, sofa" for more. A skip is said as one. */
function missedText(missed) {
  if (missed.length > 1) return "missed " + missed.length + ": " + [...new Set(missed.map((m) => m.name))].join(", ");
  const m = missed[0];
  return /^skipped \(POST/.test(m.reason || "") ? "skipped " + m.name : "missed " + m.name + ": " + sentence(m.reason);
}

/** A server sentence as part of a line: no API asides, no closing full stop, lower-case start. */
export function sentence(text) {
  const plain = withoutApi(text || "").replace(/\.$/, "");
  return plain.charAt(0).toLowerCase() + plain.slice(1);
}

/** "21:30" as the phone shows times; "Tue 21:30" for another day than today. */
export function clock(iso) {
  if (!iso) return "";
  const at = new Date(iso);
  const time = at.toLocaleTimeString([], {hour: "2-digit", minute: "2-digit"});
  return at.toDateString() === new Date().toDateString() ? time : at.toLocaleDateString([], {weekday: "short"}) + " " + time;
}
