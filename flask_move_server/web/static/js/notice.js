// What the page tells its person about the commands they gave: an error line (kept 8 s), in the
// page's own words (words.js), and a short "done" note. Every panel reports through here, so the
// wording and the timing are one. A command that succeeds clears the error of the one before.
import {words} from "./words.js";
import {$} from "./api.js";

let errorTimer = null;
let doneTimer = null;

/** Shows an error for 8 s, in words for people; `what` says what was tried ("goal", "pose", …). */
export function report(error, what) {
  $("error").textContent = words(error, what);
  clearTimeout(errorTimer);
  errorTimer = setTimeout(clearError, 8000);
}

/** A command went through: an error shown for an earlier one no longer describes the robot. */
export function clearError() {
  clearTimeout(errorTimer);
  $("error").textContent = "";
}

/** A short success note ("Saved kitchen") for 3 s; it also clears an earlier command's error. */
export function notify(text) {
  clearError();
  $("done").textContent = text;
  clearTimeout(doneTimer);
  doneTimer = setTimeout(() => { $("done").textContent = ""; }, 3000);
}

/** A tap on the error line closes it: it lies over the map, and the map is where the finger goes next. */
export function initNotices() {
  $("error").addEventListener("click", clearError);
}
