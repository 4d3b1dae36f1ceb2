// Calls to the robot's HTTP API: JSON in and out, the token in the Authorization header only.
// When a call answers 401 the page asks for the token once (every call waiting on that answer
// shares the one question), keeps it in localStorage on this device and tries the call again.

const TOKEN_KEY = "robotToken";
let token = localStorage.getItem(TOKEN_KEY) || "";
let asking = null;
let declined = false;  // the user dismissed the question: do not ask on every retry

/** The headers every call sends: the token when the device has one. */
export function authHeaders(extra = {}) {
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

/** fetch() with the token; on 401 ask once and retry once. Resolves to the Response. */
export async function authorisedFetch(path, options = {}) {
  const used = token;
  const response = await fetch(path, Object.assign({}, options, {headers: authHeaders(options.headers)}));
  if (response.status !== 401) return response;
  if (!(await askForToken(used))) return response;
  return fetch(path, Object.assign({}, options, {headers: authHeaders(options.headers)}));
}

/** One API call: resolves to the parsed JSON body ({} for 204), rejects with ApiError. */
export async function api(method, path, body) {
  const options = {method, headers: {}};
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
