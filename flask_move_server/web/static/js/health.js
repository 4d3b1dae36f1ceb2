// The Health panel: the first-boot doctor (GET /diagnostics), one row per check in colour, what
// needs doing listed first with what to do under it, and the guided box test of the laser's yaw.
import {api, $} from "./api.js";

const WORDS = {pass: "OK", warn: "Check", fail: "Fix", skip: "n/a"};
const NAMES = {
  scan: "Lidar", scan_range: "Lidar range", tf: "Frames (tf)", odom: "Odometry", move_base: "Planner",
  amcl: "Localization", localization: "Where am I", scan_match: "Laser on the map", laser_yaw: "Lidar direction", power: "Power",
  temperature: "Temperature", load: "CPU load", disk: "Disk", clock: "Clock", ros: "ROS",
  mqtt_access: "MQTT access", mqtt_identity: "MQTT name",
};
let running = false;

async function examine(box) {
  if (running) return;
  running = true;
  const status = $("health-status");
  status.dataset.level = "";
  status.textContent = box ? "Looking for the box…" : "Checking… (2 s)";
  for (const b of document.querySelectorAll("#tab-health button")) b.disabled = true;
  try {
    show(await api("GET", "/diagnostics" + (box ? "?box=1" : ""), undefined, 60000));
  } catch (e) {
    status.dataset.level = "fail";
    status.textContent = e.message;
  } finally {
    running = false;
    for (const b of document.querySelectorAll("#tab-health button")) b.disabled = false;
  }
}

function show(report) {
  const counts = {fail: 0, warn: 0};
  for (const c of report.checks) if (c.level in counts) counts[c.level] += 1;
  const status = $("health-status");
  status.dataset.level = report.status;
  status.textContent = report.status === "pass" ? "All checks pass." :
    [counts.fail && counts.fail + " to fix", counts.warn && counts.warn + " to check"].filter(Boolean).join(", ") + ".";
  // What needs doing first: fails, then warnings, then the rest, each in the doctor's order.
  const rank = (c) => ({fail: 0, warn: 1, pass: 2, skip: 3}[c.level] ?? 2);
  const ordered = report.checks.map((c, i) => [rank(c), i, c]).sort((a, b) => a[0] - b[0] || a[1] - b[1]);
  $("health").replaceChildren(...ordered.map(([, , c]) => row(c)));
  $("tab-health").scrollTop = 0;
}

function row(check) {
  const li = document.createElement("li");
  li.dataset.name = check.name;
  li.dataset.level = check.level;
  const badge = document.createElement("span");
  badge.className = "badge";
  badge.textContent = WORDS[check.level] || check.level;
  const text = document.createElement("div");
  const title = document.createElement("strong");
  title.textContent = NAMES[check.name] || check.name;
  const summary = document.createElement("span");
  summary.textContent = " " + check.summary;
  text.append(title, summary);
  if (check.advice && check.level !== "pass") {
    const advice = document.createElement("p");
    advice.textContent = check.advice;
    text.append(advice);
  }
  li.append(badge, text);
  return li;
}

/** Wires the panel: Check runs the doctor; the box test asks for a box first. */
export function initHealth() {
  $("health-check").onclick = () => examine(false);
  $("health-box").onclick = () => {
    if (window.confirm("Put a box about 1 m straight ahead of the robot, with nothing else within about "
                       + "1.5 m in any direction (behind too), then OK.")) {
      examine(true);
    }
  };
}
