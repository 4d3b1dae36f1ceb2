// The live feed: GET /events read with fetch() (EventSource cannot send the Authorization
// header, and the token must never go into a URL), parsed as Server-Sent Events.
// Reconnects by itself with back-off; tells the page when it is live or reconnecting, so the
// page can disable the controls that would act on stale state, and re-read the state after
// each reconnect. A server without /events (404) is polled through /status instead.
// The robot sends a `clock` event every 2 s: no byte for IDLE_LIMIT_MS means the link is silent
// (a Wi-Fi that stopped delivering closes no socket), and the page says so within seconds. The
// clock events also tell the robot's clock, which motion commands' `valid_until` is set on.

import {authorisedFetch, api} from "./api.js";

const IDLE_LIMIT_MS = 5000;  // no byte for this long (the robot sends its clock every 2 s): silent
const BACKOFF_MS = [500, 1000, 2000, 4000, 5000];
const POLL_MS = 200;
const BUSY_POLL_MS = 30000;  // the robot has every stream it allows open: poll this long, then try again

/** Splits a text/event-stream into events: feed() it text, it calls onEvent(type, data). */
export class SseParser {
  constructor(onEvent) {
    this.onEvent = onEvent;
    this.buffer = "";
    this.type = "";
    this.data = [];
  }

  feed(text) {
    if (this.lastWasCR && text.startsWith("\n")) text = text.slice(1);  // a CRLF split between chunks
    this.lastWasCR = text.endsWith("\r");
    this.buffer += text;
    const lines = this.buffer.split(/\r\n|\r|\n/);
    this.buffer = lines.pop();  // an unfinished line waits for the next chunk
    for (const line of lines) this.line(line);
  }

  line(line) {
    if (line === "") { this.dispatch(); return; }
    if (line.startsWith(":")) return;  // a comment: the heartbeat
    const colon = line.indexOf(":");
    const field = colon < 0 ? line : line.slice(0, colon);
    let value = colon < 0 ? "" : line.slice(colon + 1);
    if (value.startsWith(" ")) value = value.slice(1);
    if (field === "event") this.type = value;
    else if (field === "data") this.data.push(value);
  }

  dispatch() {
    if (this.data.length) this.onEvent(this.type || "message", this.data.join("\n"));
    this.type = "";
    this.data = [];
  }
}

/** The page's connection to the robot: emits events by kind and its own state. */
export class Live {
  constructor() {
    this.handlers = {};
    this.state = "connecting";
    this.onState = () => {};
    this.onConnected = () => {};
    this.failures = 0;
    this.offset = null;  // the robot's clock minus ours (s), the largest seen on this connection
  }

  /** Our best estimate of the robot's clock now (s), or null before the robot told it. */
  robotNow() { return this.offset === null ? null : performance.now() / 1000 + this.offset; }

  /** A reading of the robot's clock arrived: the least delayed one gives the largest offset. */
  clockSample(now) {
    if (typeof now !== "number") return;
    const offset = now - performance.now() / 1000;
    if (this.offset === null || offset > this.offset) this.offset = offset;
    document.body.dataset.robotClock = "known";
  }

  on(kind, handler) { (this.handlers[kind] = this.handlers[kind] || []).push(handler); }

  emit(kind, data) { for (const h of this.handlers[kind] || []) h(data); }

  setState(state) {
    if (state === this.state) return;
    this.state = state;
    this.onState(state);
    if (state === "live" || state === "polling") this.onConnected();
  }

  async start() {
    for (;;) {
      const outcome = await this.stream().catch(() => "failed");
      if (outcome === "absent") { await this.poll(Infinity); continue; }
      if (outcome === "busy") { await this.poll(BUSY_POLL_MS); continue; }
      this.setState(outcome === "unauthorised" ? "unauthorised" : "reconnecting");
      await sleep(BACKOFF_MS[Math.min(this.failures++, BACKOFF_MS.length - 1)]);
    }
  }

  /** Reads one /events stream to its end: "absent" when the server has none, "busy" when it has
   *  no stream to spare (503 too_many_streams), "unauthorised" (no or a wrong token), else "ended". */
  async stream() {
    const abort = new AbortController();
    let watchdog = setTimeout(() => abort.abort(), IDLE_LIMIT_MS);
    try {
      const response = await authorisedFetch("/events", {headers: {"Accept": "text/event-stream"}, signal: abort.signal});
      if (response.status === 404) return "absent";
      if (response.status === 401) return "unauthorised";
      if (response.status === 503) {  // busy only when every stream is taken; else (stopping) reconnect
        const body = await response.json().catch(() => ({}));
        return body.error === "too_many_streams" ? "busy" : "ended";
      }
      if (!response.ok || !response.body) return "ended";
      this.failures = 0;
      this.offset = null;  // a new connection may be to a restarted robot: learn its clock again
      document.body.dataset.robotClock = "";
      this.setState("live");
      const parser = new SseParser((type, data) => this.received(type, data));
      const reader = response.body.pipeThrough(new TextDecoderStream()).getReader();
      for (;;) {
        const {value, done} = await reader.read();
        if (done) return "ended";
        clearTimeout(watchdog);
        watchdog = setTimeout(() => abort.abort(), IDLE_LIMIT_MS);
        parser.feed(value);
      }
    } finally {
      clearTimeout(watchdog);
      abort.abort();
    }
  }

  received(type, text) {
    let data;
    try { data = JSON.parse(text); } catch (e) { return; }
    if (type === "clock") this.clockSample(data.now);
    this.emit(type, data);
  }

  /** No stream to read: read /status a few times a second instead, for `forMs`. */
  async poll(forMs) {
    const until = performance.now() + forMs;
    for (let round = 0; performance.now() < until; round++) {
      try {
        const status = await api("GET", "/status");
        if (this.state !== "polling") this.offset = null;
        this.clockSample(status.clock);
        this.setState("polling");
        this.emit("pose", status.pose);
        this.emit("status", status);
        if (status.estop) this.emit("estop", status.estop);
        this.emit("battery", status.battery);
        this.emit("dock", status.dock);
        if (round % 10 === 0) this.pollSlowly();
      } catch (e) {
        this.setState("reconnecting");
        await sleep(1000);
      }
      await sleep(POLL_MS);
    }
  }
}

/** Every couple of seconds while polling: the mode (told when it changed), the map's version, an exploration. */
Live.prototype.pollSlowly = function () {
  api("GET", "/mode").then((mode) => {
    const text = JSON.stringify(mode);
    if (text !== this.lastMode) { this.lastMode = text; this.emit("mode", mode); }
  }, () => {});
  api("GET", "/map").then((map) => this.emit("map", map), () => {});
  api("GET", "/explore").then((data) => { if (data.exploration) this.emit("explore", data.exploration); }, () => {});
};

const sleep = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
