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
