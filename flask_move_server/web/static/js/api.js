// Calls to the robot's HTTP API: JSON in and out, the token in the Authorization header only.
// Every call has a time limit: a link that silently stops delivering (a phone's Wi-Fi) gives
// "no answer" after it, and a link that is down gives "not connected", both as an ApiError with a
// code (status 0), so the page can say what happened to each command instead of "Failed to fetch".
// When a call answers 401 the page asks for the token once (every call waiting on that answer
// shares the one question), keeps it in localStorage on this device and tries the call again.

/** The page's element of id `id` (every module's `$`). */
export const $ = (id) => document.getElementById(id);
export const quietly = (promise) => promise.catch(() => {});

const TOKEN_KEY = "robotToken";
let token = localStorage.getItem(TOKEN_KEY) || "";
let asking = null;
let declined = false;  // the user dismissed the question: do not ask on every retry

/** The headers every call sends: the token when the device has one. */
function authHeaders(extra = {}) {
  const headers = Object.assign({}, extra);
  if (token) headers["Authorization"] = "Bearer " + token;
  return headers;
}

/** An error from the server, carrying its JSON `message` (what the page shows) and status. */
export class ApiError extends Error {
  constructor(status, body) {
    super((body && body.message) || "The robot answered " + status + ".");
    this.status = status;
    this.code = body && body.error;
  }
}

function askForToken(usedToken) {
  if (token !== usedToken) return Promise.resolve(true);  // another call got a new one meanwhile
  if (declined) return Promise.resolve(false);
  if (!asking) {
    asking = new Promise((resolve) => setTimeout(() => {
      const given = window.prompt("This robot needs its token (ask its owner; it stays on this device):");
      asking = null;
      if (given === null || !given.trim()) { declined = true; resolve(false); return; }
      token = given.trim();
      localStorage.setItem(TOKEN_KEY, token);
      resolve(true);
    }, 0));
  }
  return asking;
}

export const CALL_TIMEOUT_MS = 4000;  // longer than any deadline the page gives a command (3 s)

/** fetch() with the token; on 401 ask once and retry once. Resolves to the Response.
 *  With `timeout` (ms), each attempt is given up after that long: ApiError "no_answer". */
export async function authorisedFetch(path, options = {}) {
  const used = token;
  const response = await timedFetch(path, options);
  if (response.status !== 401) return response;
  if (!(await askForToken(used))) return response;
  return timedFetch(path, options);
}

async function timedFetch(path, options) {
  const init = Object.assign({}, options, {headers: authHeaders(options.headers)});
  delete init.timeout;
  if (!options.timeout) return fetch(path, init);
  const abort = new AbortController();
  if (options.signal) options.signal.addEventListener("abort", () => abort.abort());
  init.signal = abort.signal;
  const timer = setTimeout(() => abort.abort(), options.timeout);
  try {
    return await fetch(path, init);
  } catch (e) {
    if (abort.signal.aborted && !(options.signal && options.signal.aborted)) {
      throw new ApiError(0, {error: "no_answer", message: "The robot did not answer in " + options.timeout / 1000 + " s."});
    }
    throw new ApiError(0, {error: "not_connected", message: "The robot is not connected."});
  } finally {
    clearTimeout(timer);
  }
}

/** One API call: resolves to the parsed JSON body ({} for 204), rejects with ApiError.
 *  Gives up after CALL_TIMEOUT_MS (or `timeout`) with ApiError "no_answer". */
export async function api(method, path, body, timeout = CALL_TIMEOUT_MS) {
  const options = {method, headers: {}, timeout};
  if (body !== undefined) {
    options.headers["Content-Type"] = "application/json";
    options.body = JSON.stringify(body);
  }
  const response = await authorisedFetch(path, options);
  let data = {};
  if (response.status !== 204) {
    try { data = await response.json(); } catch (e) { data = {}; }
  }
  if (!response.ok) throw new ApiError(response.status, data);
  return data;
}

/** Ask for the token again (the page's "token" button), e.g. after the robot's token changed. */
export function askTokenAgain() {
  declined = false;
  return askForToken(token);
}
