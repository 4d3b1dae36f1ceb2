// What the page tells its person about the commands they gave: an error line (kept 8 s) and a
// short "done" note. Every panel reports through here, so the wording and the timing are one.

const $ = (id) => document.getElementById(id);
let errorTimer = null;

/** Shows an error (an ApiError carries the server's sentence) for 8 s. */
export function report(error) {
  $("error").textContent = error.message;
  clearTimeout(errorTimer);
  errorTimer = setTimeout(() => { $("error").textContent = ""; }, 8000);
}

let doneTimer = null;

/** A short success note ("Saved kitchen") for 3 s; it also clears an error line an earlier
 *  command left, which no longer describes the robot. */
export function notify(text) {
  clearTimeout(errorTimer);
  $("error").textContent = "";
  $("done").textContent = text;
  clearTimeout(doneTimer);
  doneTimer = setTimeout(() => { $("done").textContent = ""; }, 3000);
}

/** A tap on the error line closes it: it lies over the map, and the map is where the finger goes next. */
export function initNotices() {
  $("error").addEventListener("click", () => { clearTimeout(errorTimer); $("error").textContent = ""; });
}
