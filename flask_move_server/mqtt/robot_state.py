"""``<root>/state``: what the robot is doing, one retained JSON object, told when it changes.

``{"status", "message", "mode", "map", "target", "last_reached", "run", "estop", "pose",
"battery", "dock", "refused", "zones"}`` (docs/home-assistant.md; ``zones``: each zone's switch id, on
or off). One thread builds it once a second and at once when something is told on the event bus
(a mode, a map, waypoints, a run, an exploration, the e-stop, the robot's status: a goal sent or
ended), and publishes it when it differs from the last one told: a change reaches Home Assistant
within ``MIN_PERIOD``, and a goal shorter than a second is seen (built once a second, it was not).
The pose alone changing is told at most once a second (``POSE_PERIOD``), and never more than
``MIN_PERIOD`` apart anything else: a busy robot costs the broker a few messages a second at most. The battery
is news as for the ``battery`` event (``reporter.battery_news``: a point of charge, charging, a
reading grown old), never its ``age`` ticking, or a robot at rest would publish every second.
Pure: no paho (the link publishes), no rospy (the robot facade reads).
"""

import json
import logging
import threading
import time

from flask_move_server.core.reporter import battery_news
from flask_move_server.zones import zone_object_id

log = logging.getLogger(__name__)

PERIOD = 1.0  # s between looks when nothing is told
POSE_PERIOD = 1.0  # s: a moving robot's pose, at most this often
MIN_PERIOD = 0.1  # s between two states, whatever changed
WAKING_KINDS = ("mode", "map", "waypoints", "run", "explore", "estop", "stuck", "dock", "zone", "status")
DOCKING = ("going", "approaching", "undocking")  # dock/docking.py's states under way: "docking"
ON_THE_DOCK = ("docked", "charging")
RUNNING_EXPLORATION = ("starting", "exploring", "returning", "saving")
NAVIGATION_STATUS = {"active": "moving", "canceling": "moving", "succeeded": "arrived", "aborted": "failed",
                     "rejected": "failed", "lost": "failed", "canceled": "stopped", "stuck": "stuck"}


class RobotState:
    """Publishes the robot's state on ``<link.root>/state`` (retained) as it changes."""

    def __init__(self, link, robot, modes=None, runs=None, explorer=None, events=None,
                 refused=lambda: None, last_reached=lambda: None, battery_heard=lambda: None,
                 clock=time.monotonic, zones=lambda: ()):
        self.topic = link.root + "/state"
        self._link, self._robot, self._modes, self._runs, self._explorer = link, robot, modes, runs, explorer
        self._refused, self._last_reached, self._battery_heard = refused, last_reached, battery_heard
        self._clock = clock
        self._zones = zones  # the active map's zones (WaypointStore.zones)
        self._told = None  # (state without pose, pose) last published
        self._pose_told_at = -POSE_PERIOD
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = None
        if events is not None:
            for kind in WAKING_KINDS:
                events.listen(kind, lambda data: self.changed())
        link.when_connected(self.republish)

    def start(self):
        self._thread = threading.Thread(target=self._run, name="mqtt-state", daemon=True)
        self._thread.start()
        return self

    def changed(self):
        """Something happened: look now (never waits)."""
        self._wake.set()

    def republish(self):
        """After a (re)connect: tell the state again, even unchanged."""
        self._told = None
        self._wake.set()

    def _run(self):
        while not self._stop.is_set():
            self._wake.wait(PERIOD)
            self._wake.clear()
            if self._stop.is_set():
                return
            try:
                self.tell()
            except Exception:  # a part's bug must not end the state topic
                log.exception("MQTT: building the robot's state failed")
            self._stop.wait(MIN_PERIOD)

    def tell(self):
        """Build the state and publish it if it is news; True when published."""
        state = self.build()
        pose = state.pop("pose")
        now = self._clock()
        told = self._told
        news = (told is None or _but_battery(state) != _but_battery(told[0])
                or battery_news(told[0]["battery"], state["battery"]))
        pose_news = told is not None and pose != told[1] and now - self._pose_told_at >= POSE_PERIOD
        if not (news or pose_news):
            return False
        if state["battery"] is not None and (told is None or told[0]["battery"] is None):
            self._battery_heard()  # Home Assistant's Battery sensor is due
        self._told = (state, pose)
        self._pose_told_at = now
        self._link.publish(self.topic, json.dumps(dict(state, pose=pose), ensure_ascii=False), retain=True)
        return True

    def build(self):
        """The state as a dict (see the module's docstring)."""
        status = self._robot.status()
        nav = status.get("navigation") or {}
        estop = bool((status.get("estop") or {}).get("latched"))
        mode = self._modes.status() if self._modes is not None else {}
        run = self._runs.active() if self._runs is not None else None
        exploring = self._exploring()
        stuck = status.get("stuck") or {}
        stuck = stuck if stuck.get("state") not in (None, "free") else None
        dock = (status.get("dock") or {}).get("state")
        told = _status(nav, status.get("teleop") or {}, estop, run, exploring, dock)
        return {
            "status": "stuck" if stuck and not estop else told,
            "message": stuck["message"] if stuck else _message(nav, status.get("dock"), told),
            "mode": mode.get("mode"),
            "map": mode.get("map"),
            "target": nav.get("target") if nav.get("state") in ("active", "canceling") else None,
            "last_reached": self._last_reached(),
            "run": _run_summary(run),
            "estop": estop,
            "pose": _pose(status.get("pose")),
            "battery": status.get("battery"),
            "dock": dock,
            "refused": self._refused(),
            "zones": {zone_object_id(z.name): z.enabled for z in self._zones()},
        }

    def _exploring(self):
        exp = self._explorer.current() if self._explorer is not None else None
        return exp is not None and exp["state"] in RUNNING_EXPLORATION

    def close(self):
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=2)


def _but_battery(state):
    return dict(state, battery=None)


def _status(nav, teleop, estop, run, exploring, dock=None):
    """One word for what the robot does: estop, exploring, paused, docking, moving, teleop, charging, docked,
    arrived, failed, stopped, idle (``stuck`` comes before it all but the e-stop: see build)."""
    if estop:
        return "estop"
    if exploring:
        return "exploring"
    if run is not None and run["state"] in ("paused", "stuck"):
        return run["state"]
    if dock in DOCKING:
        return "docking"
    if nav.get("state") in ("active", "canceling"):
        return "moving"
    if teleop.get("active"):
        return "teleop"
    if dock in ON_THE_DOCK:
        return dock
    return NAVIGATION_STATUS.get(nav.get("state"), "idle")


def _message(nav, dock, told):
    """The docking's words while it docks or is docked (or failed), else move_base's."""
    if dock and (told in ("docking", "charging", "docked") or dock.get("state") == "failed"):
        return dock.get("message")
    return nav.get("message")


def _run_summary(run):
    if run is None:
        return None
    return {"id": run["id"], "route": run.get("route"), "state": run["state"]}


def _pose(pose):
    """The pose rounded to what a dashboard shows: cm and 0.01 rad (so jitter is not news)."""
    if not pose:
        return None
    return {"x": round(pose["x"], 2), "y": round(pose["y"], 2), "yaw": round(pose["yaw"], 2)}
