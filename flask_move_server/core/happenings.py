"""Happenings: what the robot did that its owner may want to hear of, each by name, told once.

The names (the ``events`` a webhook lists, config.WEBHOOK_EVENTS) and their data:

- ``arrived``: a goal succeeded. ``{"target", "goal", "goal_id"}``: the waypoint name (None for a
  goal to x, y), the goal's pose ``{"x", "y", "yaw"}``, its sequence number (``/status``'s ``goal_id``).
- ``failed``: a goal ended without arriving and nobody asked it to stop: move_base aborted or
  rejected it (or lost it), or the server gave it up (no ROS master, no acknowledgement, a mode
  switch). ``{"target", "state", "message", "goal_id"}``, ``message`` the sentence ``/status`` says.
- ``run_done``: a run ended (``succeeded``, ``failed``, ``canceled``, or ``skipped`` by a schedule
  that found the robot busy); the data is the run as ``GET /runs/<id>`` shows it. Once per run.
- ``estop``: the e-stop latch engaged (not again for a press while it is latched). ``{"source"}``.
- ``explore_done``: an exploration ended (``done``, ``failed``, ``canceled``); the data is the
  exploration as ``GET /explore`` shows it. Once per exploration.
- ``stuck``: the robot noticed it is stuck (``recovery/``): ``/status``'s ``stuck`` as it was then
  (``{"state", "message", "since", "place", "count", "freed"}``). Once each time, exploring too; a
  goal that then ends ``stuck`` is also ``failed``.
- ``docked``: a docking (``POST /dock``, ``dock/``) brought the robot onto its charger; ``dock_failed``:
  one gave up (at the staging pose, ``message`` says why). The data is ``/status``'s ``dock`` then
  (``{"state", "place", "tries", "confirmed", "message"}``). Once per docking.
- ``low_battery``: the battery fell below ``dock.return_below`` and the robot goes home by itself
  (``dock/low_battery.py``): ``{"percentage", "place", "run"}``, ``run`` the id of the run it paused
  (or None). Once per fall below it.

A goal canceled (``POST /stop``, a run paused, teleop) or replaced by a newer goal is neither
``arrived`` nor ``failed``. While an exploration is under way its own goals (frontiers, the way
home) are not told: move_base giving up on a frontier is part of exploring; ``explore_done`` says
how it went; nor are a docking's (its staging pose): ``docked`` or ``dock_failed`` says.
``last_reached`` keeps the last waypoint reached (exploring too).

Listeners are called as ``callback(name, data)`` in the thread where it happened (actionlib's, a
request's, the run executor's): they must not block (the webhooks queue it); an exception is
logged, never raised to the robot. Pure: no rospy, no Flask.
"""

import datetime
import logging
import threading
from collections import OrderedDict

from flask_move_server.explore.exploration import ENDED as EXPLORE_ENDS
from flask_move_server.missions.history import ENDED as RUN_ENDS

log = logging.getLogger(__name__)

ARRIVED, FAILED, RUN_DONE, ESTOP, EXPLORE_DONE, STUCK, DOCKED, DOCK_FAILED, LOW_BATTERY = (
    "arrived", "failed", "run_done", "estop", "explore_done", "stuck", "docked", "dock_failed", "low_battery")
NAMES = (ARRIVED, FAILED, RUN_DONE, ESTOP, EXPLORE_DONE, STUCK, DOCKED, DOCK_FAILED, LOW_BATTERY)
DOCKING = ("going", "approaching", "undocking")  # dock/docking.py: its own goal (the staging pose) is not told
GOAL_FAILURES = ("aborted", "rejected", "lost", "stuck")  # the navigator reads a lost goal as aborted
RUNS_REMEMBERED = 200  # run ids whose end was told: a late repeat of an ended run's event is not told again


def utc_now_iso():
    """Now, ISO 8601 in UTC to the millisecond: ``2024-05-01T12:00:00.123+00:00``."""
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="milliseconds")


class Happenings:
    """Hears the robot's parts and tells named happenings to its listeners.

    ``robot``: the facade (its ``navigator.when_ended`` and ``estop.when_engaged`` are used);
    ``events``: the event bus (``run`` and ``explore`` kinds), or None.
    """

    def __init__(self, robot, events=None, clock=utc_now_iso):
        self._clock = clock
        self._estop = robot.estop
        self._lock = threading.Lock()
        self._listeners = []
        self._closed = False
        self._last_reached = None
        self._runs_told = OrderedDict()  # run id -> None, the newest RUNS_REMEMBERED
        self._exploring = False
        self._explore_told = None  # (started, save_as) of the last exploration whose end was told
        self._estop_told = 0  # the latch's engagements when the last was told
        self._stuck_told = 0  # the stuck count when the last was told
        self._dock_state = None  # the dock's state last heard
        robot.navigator.when_ended(self._goal_ended)
        robot.estop.when_engaged(self._estop_engaged)
        if events is not None:
            events.listen("run", self._run_changed)
            events.listen("explore", self._explore_changed)
            events.listen("stuck", self._stuck_changed)
            events.listen("dock", self._dock_changed)

    def listen(self, callback):
        """Call ``callback(name, data)`` on every happening, in the thread where it happened (sometimes under
        the run executor's or the explorer's lock): queue, never block nor call back into the robot. ``data``
        is shared by every listener: read it, do not change it."""
        with self._lock:
            self._listeners.append(callback)

    @property
    def last_reached(self):
        """``{"name", "at"}`` of the last waypoint a goal reached (``at`` ISO 8601 UTC), or None."""
        with self._lock:
            return dict(self._last_reached) if self._last_reached is not None else None

    def close(self):
        """Tell nothing more (the server is stopping). Idempotent."""
        with self._lock:
            self._closed = True
            self._listeners = []

    # the sources -----------------------------------------------------------------------------

    def _goal_ended(self, seq, state, target, pose, why):
        """Navigator.when_ended: ``arrived`` or ``failed``; a canceled or replaced goal tells nothing."""
        with self._lock:
            if state == "succeeded" and target is not None:
                self._last_reached = {"name": target, "at": self._clock()}
            exploring = self._exploring or self._dock_state in DOCKING
        if exploring:
            return
        if state == "succeeded":
            self._tell(ARRIVED, {"target": target, "goal": pose.as_dict() if pose is not None else None,
                                 "goal_id": seq})
        elif state in GOAL_FAILURES:
            self._tell(FAILED, {"target": target, "state": state, "message": why, "goal_id": seq})

    def _estop_engaged(self, source):
        """EStop.when_engaged: ``estop`` once per engagement (a second press while latched is not one)."""
        engagements = self._estop.engagements
        with self._lock:
            if engagements == self._estop_told:
                return
            self._estop_told = engagements
        self._tell(ESTOP, {"source": source})

    def _run_changed(self, run):
        """The ``run`` event: ``run_done`` the first time a run is seen in an end state."""
        if not isinstance(run, dict) or run.get("state") not in RUN_ENDS:
            return
        with self._lock:
            if run.get("id") in self._runs_told:
                return
            self._runs_told[run.get("id")] = None
            while len(self._runs_told) > RUNS_REMEMBERED:
                self._runs_told.popitem(last=False)
        self._tell(RUN_DONE, dict(run))

    def _explore_changed(self, exploration):
        """The ``explore`` event: under way (its goals are not told), or ``explore_done`` once it ends."""
        if not isinstance(exploration, dict):
            return
        with self._lock:
            if exploration.get("state") not in EXPLORE_ENDS:
                self._exploring = True
                return
            key = (exploration.get("started"), exploration.get("save_as"))
            first = self._exploring or key != self._explore_told
            self._exploring, self._explore_told = False, key
        if first:
            self._tell(EXPLORE_DONE, dict(exploration))

    def _stuck_changed(self, stuck):
        """The ``stuck`` event: ``stuck`` once each time the robot noticed it (its count grew)."""
        if not isinstance(stuck, dict) or stuck.get("state") == "free":
            return
        with self._lock:
            if stuck.get("count", 0) <= self._stuck_told:
                return
            self._stuck_told = stuck.get("count", 0)
        self._tell(STUCK, dict(stuck))

    def _dock_changed(self, dock):
        """The ``dock`` event: ``docked`` as a docking reaches the charger, ``dock_failed`` as one gives up."""
        if not isinstance(dock, dict):
            return
        state = dock.get("state")
        with self._lock:
            before, self._dock_state = self._dock_state, state
        if state in ("docked", "charging") and before in DOCKING:
            self._tell(DOCKED, dict(dock))
        elif state == "failed" and before != "failed":
            self._tell(DOCK_FAILED, dict(dock))

    def low_battery(self, data):
        """dock/low_battery.py: the robot goes home on a low battery."""
        self._tell(LOW_BATTERY, dict(data))

    def _tell(self, name, data):
        with self._lock:
            listeners = [] if self._closed else list(self._listeners)
        for callback in listeners:
            try:
                callback(name, data)
            except Exception:  # a listener's bug must not reach the robot's thread (actionlib, a request)
                log.exception("a listener of %r happenings failed", name)
