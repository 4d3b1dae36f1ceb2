// What the page tells its person about the commands they gave: an error line (kept 8 s), in the
// page's own words (words.js), and a short "done" note. Every panel reports through here, so the
// wording and the timing are one. A command that succeeds clears the error of the one before.
import {words} from "./words.js";

const $ = (id) => document.getElementById(id);
let errorTimer = null;

/** Shows an error for 8 s, in words for people; `what` says what was tried ("goal", "pose", …). */
export function report(error, what) {
  show(words(error, what), "error", 8000);
}

/** A short note that something was done ("Saved kitchen"), 3 s. */
export function notify(text) {
  show(text, "done", 3000);
}

/** A command went through: an error shown for an earlier one no longer applies. */
export function clearError() {
  if ($("error").dataset.level === "error") show("", "", 0);
}

function show(text, level, ms) {
  const line = $("error");
  line.textContent = text;
  line.dataset.level = level;
  clearTimeout(errorTimer);
  if (ms) errorTimer = setTimeout(() => { line.textContent = ""; line.dataset.level = ""; }, ms);
}
