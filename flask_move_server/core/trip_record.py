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
import math

from flask_move_server.core import names
from flask_move_server.core.errors import BadRequest
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
        return INTERRUPTED.format(_where(data))

    def started(self, goal):
        self._writer.write(json.dumps({"target": goal.target, "goal": goal.pose.as_dict()}) + "\n")

    def ended(self):
        self._writer.remove()

    def close(self):
        """Write what is pending, then stop the thread."""
        self._writer.close()


POSITION_LIMIT = 1e6  # m: as the API bounds a pose (waypoints.POSITION_LIMIT)


def _where(data):
    """Where the kept trip went, in words, from values checked as the API checks them (a hand edit or a
    file of another version may hold anything): the place's name, else its position, else "a goal"."""
    target = data.get("target")
    try:
        return names.checked(target, "place", BadRequest) if target is not None else _position(data.get("goal"))
    except BadRequest:
        return _position(data.get("goal"))


def _position(goal):
    if isinstance(goal, dict):
        x, y = goal.get("x"), goal.get("y")
        if all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and
               abs(v) <= POSITION_LIMIT for v in (x, y)):
            return "x {:.1f}, y {:.1f}".format(x, y)
    return "a goal"
