"""The trip under way, kept on disk, so a restart can say it interrupted one.

A robot on its way to the kitchen when its server restarts (a crash, a power cut, an update)
stands still afterwards, and the page used to say "tap a place" as if nothing had happened.
``trip.json`` in the state folder holds the goal while it is under way and is removed when it
ends; one found at start means the trip was interrupted, and the navigation status says so
until the next goal. The robot never drives off by itself after a restart.

Written by a thread of its own (atomically: the waypoints file's plumbing), never in the
request that sends the goal: an SD card's fsync can take tens of milliseconds, and ``/goto``
answers in one. Only the newest wish is written; a crash within that moment loses the note,
never a goal. Pure: no rospy, no Flask.
"""

import json
import logging
import os
import threading

from flask_move_server.errors import WaypointFileError
from flask_move_server.waypoints import locked_file

log = logging.getLogger(__name__)

INTERRUPTED = ("The trip to {} was interrupted: the robot's server restarted while it was under way. "
               "Send it again if you still want it.")


class TripRecord:
    """``started(goal)`` / ``ended()`` from the navigator; ``left_over()`` once at start."""

    def __init__(self, path):
        self.path = path
        self._cond = threading.Condition()
        self._wish = None  # ("write", text) or ("remove", None): the newest state to put on disk
        self._closed = False
        self._thread = threading.Thread(target=self._run, name="trip-record", daemon=True)
        self._thread.start()

    def left_over(self):
        """The sentence for a trip a restart interrupted (and the note removed), or None."""
        try:
            with open(self.path, encoding="utf-8") as f:
                data = json.loads(f.read(4096))
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as exc:
            log.warning("ignoring %s: %s", self.path, exc)
            data = None
        self._want("remove", None)
        if not isinstance(data, dict):
            return None
        where = data.get("target")
        goal = data.get("goal") or {}
        if not isinstance(where, str):
            where = "x {:.1f}, y {:.1f}".format(goal.get("x", 0.0), goal.get("y", 0.0)) if goal else "a goal"
        return INTERRUPTED.format(where)

    def started(self, goal):
        self._want("write", json.dumps({"target": goal.target, "goal": goal.pose.as_dict()}) + "\n")

    def ended(self):
        self._want("remove", None)

    def _want(self, what, text):
        with self._cond:
            self._wish = (what, text)
            self._cond.notify()

    def _run(self):
        while True:
            with self._cond:
                while self._wish is None and not self._closed:
                    self._cond.wait()
                wish, self._wish = self._wish, None
            if wish is None:
                return
            self._apply(*wish)

    def _apply(self, what, text):
        try:
            if what == "write":
                os.makedirs(os.path.dirname(os.path.abspath(self.path)), exist_ok=True)
                locked_file.atomic_write(self.path, text)
            elif os.path.exists(self.path):
                os.unlink(self.path)
        except (OSError, WaypointFileError) as exc:
            log.warning("could not keep the trip under way in %s: %s", self.path, exc)

    def close(self):
        """Write what is pending, then stop the thread."""
        with self._cond:
            self._closed = True
            self._cond.notify()
        self._thread.join(5)
