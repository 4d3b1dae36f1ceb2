"""The trip under way, kept on disk, so a restart can say it interrupted one.

A robot on its way to the kitchen when its server restarts (a crash, a power cut, an update)
stands still afterwards, and the page used to say "tap a place" as if nothing had happened.
``trip.json`` in the state folder holds the goal while it is under way and is removed when it
ends; one found at start means the trip was interrupted, and the navigation status says so
until the next goal. The robot never drives off by itself after a restart.

Written by a :class:`~flask_move_server.core.state_writer.StateWriter` (its own thread, atomically),
never in the request that sends the goal: ``/goto`` answers in a millisecond. Pure: no rospy, no Flask.
"""

import json
import logging

from flask_move_server.core.state_writer import StateWriter

log = logging.getLogger(__name__)

INTERRUPTED = ("The trip to {} was interrupted: the robot's server restarted while it was under way. "
               "Send it again if you still want it.")


class TripRecord:
    """``started(goal)`` / ``ended()`` from the navigator; ``left_over()`` once at start."""

    def __init__(self, path):
        self.path = path
        self._writer = StateWriter(path, "the trip under way", "trip-record")

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
        self._writer.remove()
        if not isinstance(data, dict):
            return None
        where = data.get("target")
        goal = data.get("goal") or {}
        if not isinstance(where, str):
            where = "x {:.1f}, y {:.1f}".format(goal.get("x", 0.0), goal.get("y", 0.0)) if goal else "a goal"
        return INTERRUPTED.format(where)

    def started(self, goal):
        self._writer.write(json.dumps({"target": goal.target, "goal": goal.pose.as_dict()}) + "\n")

    def ended(self):
        self._writer.remove()

    def close(self):
        """Write what is pending, then stop the thread."""
        self._writer.close()
