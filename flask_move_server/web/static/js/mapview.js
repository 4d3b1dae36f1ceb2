// The map on a canvas: the server's PNG, the robot, its plan and goal, the waypoints, and the
// gestures (press-and-drag for a pose with a heading, like RViz's 2D Nav Goal; two fingers or
// the wheel to pan and zoom). Metres <-> screen: sx = ox + x * scale, sy = oy - y * scale.
// The PNG's row 0 is the TOP (largest y) of the crop, so pixel (col, row) covers
// x = origin.x + col * res .. + res and y = origin.y + (height - row - 1) * res .. + res.
// State tests read is mirrored into data-* attributes of the canvas.

import {drawMap, TAP_PX} from "./mapdraw.js";

const HIT_PX = 24;        // a tap this close to a waypoint marker picks it
const STALE_AGE_S = 1.5;  // a pose this old when the server read it greys the robot
const SILENT_MS = 3500;   // the server tells the pose at least once a second, even at rest
const MIN_SCALE = 2, MAX_SCALE = 800;
const TRAIL_POINTS = 500; // poses kept for the trail (at 5 cm apart, the last 25 m driven)
const TRAIL_STEP_M = 0.05; // a pose closer than this to the last kept one adds nothing
const TRAIL_JUMP_M = 1.0;  // a longer step is a jump (a new pose set), not driven: no line across it

export class MapView {
  /** `overlays`: controls laid over the canvas (the gesture bar) that fit() keeps the map clear of. */
  constructor(canvas, {overlays = []} = {}) {
    this.canvas = canvas;
    this.overlays = overlays;
    this.ctx = canvas.getContext("2d");
    this.meta = null;            // {resolution, originX, originY, width, height, version}
    this.image = null;           // an ImageBitmap of /map/image
    this.view = {scale: 40, ox: 0, oy: 0};
    this.fitted = false;         // the view was fitted to a map (else it follows what is known)
    this.userMoved = false;      // a person panned or zoomed: leave the view alone
    this.follow = false;
    this.robot = null;           // the newest pose {x, y, yaw, age, at}
    this.drawn = null;           // where the robot is drawn now (eased towards this.robot)
    this.plan = [];
    this.goal = null;
    this.waypoints = [];
    this.labels = [];            // the waypoint labels as drawn: {name, text, box}
    this.scan = [];              // the laser's echoes [[x, y], ...] in the map frame, newest scan
    this.scanSeen = 0;           // scans received, for the tests
    this.showScan = true;
    this.trail = [];             // where the robot went [[x, y] or null (a jump), ...], oldest first
    this.draft = null;           // a route being made [{name, state}] in order, shown before a run's
    this.runStops = null;        // the run under way's stops [{name, state}]: its progress
    this.exploreTarget = null;   // [x, y]: where the exploration under way is heading
    this.zones = [];             // the map's zones as GET /zones gives them (zonedraw.js)
    this.zoneDraft = null;       // a zone being drawn or edited: {kind, points: [[x, y], ...], name, picked, before}
    this.mode = "go";            // what a one-finger press does: go | pose | mark | look | route (tap places, pan) | zone
    this.pointers = new Map();
    this.gesture = null;
    this.onPress = () => {};     // (mode, x, y, yaw) from a drag or a tap on the map
    this.onWaypoint = () => {};  // (name) from a tapped marker
    this.onTap = () => {};       // (mode) a tap on no marker
    this.onWaypoints = () => {}; // (list) the waypoints shown changed
    this.onRouteStop = () => {}; // (name) a place tapped while making a route
    this.onZonePoint = () => {}; // (x, y) a spot tapped while drawing a zone
    this.listen();
    new ResizeObserver(() => this.resize()).observe(canvas);
    this.resize();
    this.frame = this.frame.bind(this);
    requestAnimationFrame(this.frame);
  }

  // -- what it shows --

  /** Shows the map `GET /map` describes (`meta`) as `image`; null: no map in use now. */
  setMap(meta, image) {
    if (!meta) {
      this.meta = this.image = null;
      this.canvas.dataset.mapVersion = "";
      return;
    }
    const origin = Array.isArray(meta.origin) ? meta.origin : [meta.origin.x, meta.origin.y];
    this.meta = {resolution: meta.resolution, originX: origin[0], originY: origin[1],
                 width: meta.width, height: meta.height, version: meta.version};
    this.image = image;
    this.canvas.dataset.mapVersion = String(meta.version);
    if (!this.fitted) this.fit();
  }

  setPose(pose) {
    if (!pose) {  // no pose now: keep the last one on the map, greyed
      if (this.robot) this.robot.age = Infinity;
      return;
    }
    this.robot = {x: pose.x, y: pose.y, yaw: pose.yaw, age: pose.age || 0, at: performance.now()};
    this.extendTrail(pose);
    if (!this.drawn) this.drawn = {x: pose.x, y: pose.y, yaw: pose.yaw};
    if (!this.meta && !this.userMoved && !this.robotSeen) { this.robotSeen = true; this.fit(); }
  }

  setPlan(poses) { this.plan = poses || []; }
  setScan(points) { this.scan = points || []; this.scanSeen += 1; }
  clearTrail() { this.trail = []; }

  /** Keeps the pose for the trail when it moved; a jump starts a new piece of line. */
  extendTrail(pose) {
    const last = this.trail[this.trail.length - 1];
    const step = last ? Math.hypot(pose.x - last[0], pose.y - last[1]) : Infinity;
    if (step < TRAIL_STEP_M) return;
    if (last && step > TRAIL_JUMP_M) this.trail.push(null);
    this.trail.push([pose.x, pose.y]);
    if (this.trail.length > TRAIL_POINTS) this.trail.splice(0, this.trail.length - TRAIL_POINTS);
  }

  /** The scan as drawn now: none while hidden or while the robot is not connected (it would be old). */
  scanShown() { return this.showScan && !this.offline ? this.scan : []; }
  setGoal(goal) { this.goal = goal; }
  /** The route drawn: the one being made, else the run under way's progress, else none. */
  routeShown() { return this.draft || this.runStops || []; }
  setWaypoints(list) {
    this.waypoints = list;
    this.onWaypoints(list);
    this.canvas.dispatchEvent(new CustomEvent("waypoints"));  // for more than one listener (the route editor)
    if (!this.meta && !this.userMoved) this.fit();
  }

  /** What the map shows at (x, y) m: "free", "wall" or "unknown" (off the map too); null without a map.
   *  The PNG is map_saver's: free 254, unknown 205, occupied 0. */
  cellAt(x, y) {
    const m = this.meta;
    if (!m || !this.image) return null;
    const col = Math.floor((x - m.originX) / m.resolution), row = m.height - 1 - Math.floor((y - m.originY) / m.resolution);
    if (col < 0 || row < 0 || col >= m.width || row >= m.height) return "unknown";
    const value = this.pixels()[(row * m.width + col) * 4];
    return value >= 240 ? "free" : value <= 100 ? "wall" : "unknown";
  }

  /** The map image's RGBA bytes, read once per image through an offscreen canvas. */
  pixels() {
    if (this.pixelsOf !== this.image) {
      const {width, height} = this.image;
      const canvas = Object.assign(document.createElement("canvas"), {width, height});  // not OffscreenCanvas: iOS < 16.4
      const scratch = canvas.getContext("2d", {willReadFrequently: true});
      scratch.drawImage(this.image, 0, 0);
      this.pixelData = scratch.getImageData(0, 0, width, height).data;
      this.pixelsOf = this.image;
    }
    return this.pixelData;
  }

  /** Stale: the server's pose was old when read, no pose came for a while (the server repeats
   *  it every second at rest), or the page has lost the robot. */
  robotStale() {
    const r = this.robot;
    return !r || r.age > STALE_AGE_S || performance.now() - r.at > SILENT_MS || Boolean(this.offline);
  }

  // -- view --

  resize() {
    const ratio = window.devicePixelRatio || 1;
    const rect = this.canvas.getBoundingClientRect();
    this.width = rect.width;
    this.height = rect.height;
    this.canvas.width = Math.round(rect.width * ratio);
    this.canvas.height = Math.round(rect.height * ratio);
    this.ctx.setTransform(ratio, 0, 0, ratio, 0, 0);
    if (!this.userMoved) this.fit();
  }

  /** The area worth showing: the map's crop, else the waypoints and the robot. */
  bounds() {
    if (this.meta) {
      const m = this.meta, r = m.resolution;
      return [m.originX, m.originY, m.originX + m.width * r, m.originY + m.height * r];
    }
    const points = this.waypoints.map((w) => [w.x, w.y]);
    if (this.robot) points.push([this.robot.x, this.robot.y]);
    if (!points.length) return [-5, -5, 5, 5];
    const xs = points.map((p) => p[0]), ys = points.map((p) => p[1]);
    return [Math.min(...xs) - 1, Math.min(...ys) - 1, Math.max(...xs) + 1, Math.max(...ys) + 1];
  }

  /** The canvas less the controls over it, [left, top, width, height]: a bar along the bottom
   *  takes its height off the bottom, a column at the left its width off the left. */
  usableArea() {
    let [left, bottom] = [0, this.height];
    const c = this.canvas.getBoundingClientRect();
    for (const el of this.overlays) {
      const o = el.getBoundingClientRect();
      if (!o.width || !o.height) continue;
      if (o.width >= o.height) bottom = Math.min(bottom, o.top - c.top);
      else left = Math.max(left, o.right - c.left);
    }
    return [left, 0, this.width - left, Math.max(bottom, this.height / 2)];
  }

  fit() {
    if (!this.width || !this.height) return;
    const [x0, y0, x1, y1] = this.bounds();
    const [left, top, width, height] = this.usableArea();
    const scale = Math.min(width / Math.max(x1 - x0, 0.5), height / Math.max(y1 - y0, 0.5)) * 0.95;
    this.view.scale = clamp(scale, MIN_SCALE, MAX_SCALE);
    this.view.ox = left + width / 2 - (x0 + x1) / 2 * this.view.scale;
    this.view.oy = top + height / 2 + (y0 + y1) / 2 * this.view.scale;
    this.fitted = Boolean(this.meta);
    this.userMoved = false;
    this.follow = false;
  }

  centreOn(x, y) {
    this.view.ox = this.width / 2 - x * this.view.scale;
    this.view.oy = this.height / 2 + y * this.view.scale;
  }

  toScreen(x, y) { return [this.view.ox + x * this.view.scale, this.view.oy - y * this.view.scale]; }
  toWorld(sx, sy) { return [(sx - this.view.ox) / this.view.scale, (this.view.oy - sy) / this.view.scale]; }

  zoomAbout(sx, sy, factor) {
    const [x, y] = this.toWorld(sx, sy);
    this.view.scale = clamp(this.view.scale * factor, MIN_SCALE, MAX_SCALE);
    this.view.ox = sx - x * this.view.scale;
    this.view.oy = sy + y * this.view.scale;
  }

  // -- gestures --

  listen() {
    const c = this.canvas;
    c.addEventListener("pointerdown", (e) => this.down(e));
    c.addEventListener("pointermove", (e) => this.move(e));
    c.addEventListener("pointerup", (e) => this.up(e, false));
    c.addEventListener("pointercancel", (e) => this.up(e, true));
    c.addEventListener("wheel", (e) => {
      e.preventDefault();
      const p = this.local(e);
      this.zoomAbout(p[0], p[1], Math.exp(-e.deltaY / 300));
      this.userMoved = true;
    }, {passive: false});
  }

  local(e) {
    const r = this.canvas.getBoundingClientRect();
    return [e.clientX - r.left, e.clientY - r.top];
  }

  down(e) {
    this.canvas.setPointerCapture(e.pointerId);
    this.pointers.set(e.pointerId, this.local(e));
    if (this.pointers.size === 1) {
      const start = this.local(e);
      this.gesture = {kind: "press", start, now: start, view: Object.assign({}, this.view)};
    } else if (this.pointers.size === 2) {
      const [a, b] = [...this.pointers.values()];
      this.gesture = {kind: "pinch", mid: midpoint(a, b), dist: distance(a, b), view: Object.assign({}, this.view)};
      this.follow = false;
      this.userMoved = true;
    }
  }

  move(e) {
    if (!this.pointers.has(e.pointerId) || !this.gesture) return;
    this.pointers.set(e.pointerId, this.local(e));
    const g = this.gesture;
    if (g.kind === "pinch" && this.pointers.size >= 2) {
      const [a, b] = [...this.pointers.values()];
      const mid = midpoint(a, b);
      const scale = clamp(g.view.scale * distance(a, b) / Math.max(g.dist, 1), MIN_SCALE, MAX_SCALE);
      const wx = (g.mid[0] - g.view.ox) / g.view.scale, wy = (g.view.oy - g.mid[1]) / g.view.scale;
      this.view = {scale, ox: mid[0] - wx * scale, oy: mid[1] + wy * scale};
    } else if (g.kind === "press") {
      g.now = this.local(e);
      if (this.mode === "look" || this.mode === "route" || this.mode === "zone") {
        this.view.ox = g.view.ox + g.now[0] - g.start[0];
        this.view.oy = g.view.oy + g.now[1] - g.start[1];
        if (distance(g.start, g.now) > TAP_PX) { this.follow = false; this.userMoved = true; }
      }
    }
  }

  up(e, cancelled) {
    this.pointers.delete(e.pointerId);
    const g = this.gesture;
    if (!g) return;
    if (g.kind === "pinch") {
      if (this.pointers.size === 0) this.gesture = null;
      return;
    }
    this.gesture = null;
    if (cancelled || this.mode === "look") return;
    if (distance(g.start, g.now) < TAP_PX) { this.tap(g.start); return; }
    if (this.mode === "route" || this.mode === "zone") return;  // a drag while making a route or a zone pans
    const [x, y] = this.toWorld(g.start[0], g.start[1]);
    const yaw = Math.atan2(-(g.now[1] - g.start[1]), g.now[0] - g.start[0]);
    this.onPress(this.mode, x, y, yaw);
  }

  /** A tap picks a waypoint in Go mode (or adds it to a route being made); anywhere else it only
   *  says how to send the robot (a stray touch while looking at the map must not move a robot). */
  tap(point) {
    if (this.mode === "zone") { this.onZonePoint(...this.toWorld(point[0], point[1])); return; }
    const hit = this.waypointAt(point);
    if (hit && this.mode === "go") { this.onWaypoint(hit.name); return; }
    if (hit && this.mode === "route") { this.onRouteStop(hit.name); return; }
    this.onTap(this.mode);
  }

  waypointAt(point) {
    let best = null, bestDist = HIT_PX;
    for (const w of this.waypoints) {
      const d = distance(point, this.toScreen(w.x, w.y));
      if (d < bestDist) { best = w; bestDist = d; }
    }
    return best;
  }

  // -- drawing --

  frame(now) {
    this.ease(now);
    if (this.follow && this.drawn) this.centreOn(this.drawn.x, this.drawn.y);
    this.draw();
    this.publish();
    requestAnimationFrame(this.frame);
  }

  /** Moves the drawn robot towards the newest pose: smooth between updates, never far behind. */
  ease(now) {
    const t = this.robot, d = this.drawn;
    if (!t || !d) return;
    const k = 1 - Math.exp(-(now - (this.lastFrame || now)) / 60);
    this.lastFrame = now;
    d.x += (t.x - d.x) * k;
    d.y += (t.y - d.y) * k;
    d.yaw += wrap(t.yaw - d.yaw) * k;
    if (Math.hypot(t.x - d.x, t.y - d.y) < 1e-4) { d.x = t.x; d.y = t.y; }
  }

  draw() { drawMap(this); }

  imageRect() {
    const m = this.meta, r = m.resolution;
    const [left, top] = this.toScreen(m.originX, m.originY + m.height * r);
    return [left, top, m.width * r * this.view.scale, m.height * r * this.view.scale];
  }

  /** State for tests and for people reading the DOM: where things are drawn, in CSS pixels. */
  publish() {
    const ds = this.canvas.dataset;
    const robot = this.drawn && this.robot ? this.toScreen(this.drawn.x, this.drawn.y) : null;
    set(ds, "robotPx", robot ? robot.map((v) => v.toFixed(1)).join(",") : "");
    set(ds, "robotStale", this.robotStale() ? "1" : "0");
    set(ds, "imageRect", this.image && this.meta ? this.imageRect().map((v) => v.toFixed(2)).join(",") : "");
    set(ds, "view", [this.view.scale, this.view.ox, this.view.oy].map((v) => v.toFixed(3)).join(","));
    set(ds, "follow", this.follow ? "1" : "0");
    set(ds, "planPoints", String(this.plan.length));
    set(ds, "labels", JSON.stringify(this.labels.map((l) => ({name: l.name, text: l.text, box: l.box.map(Math.round)}))));
    set(ds, "scanPoints", String(this.scanShown().length));
    set(ds, "scanSeen", String(this.scanSeen));
    set(ds, "route", JSON.stringify(this.routeShown()));
    set(ds, "trailPoints", String(this.trail.filter(Boolean).length));
    set(ds, "exploreTarget", this.exploreTarget ? this.exploreTarget.join(",") : "");
  }
}

function set(dataset, key, value) { if (dataset[key] !== value) dataset[key] = value; }
function clamp(v, lo, hi) { return Math.max(lo, Math.min(hi, v)); }
function wrap(a) { return Math.atan2(Math.sin(a), Math.cos(a)); }
function midpoint(a, b) { return [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2]; }
function distance(a, b) { return Math.hypot(a[0] - b[0], a[1] - b[1]); }
