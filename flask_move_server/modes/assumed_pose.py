"""Whether the robot's pose is one the server assumed, or one a person gave or confirmed.

After a switch to navigation on a named map (and so after every restart, which comes back to
it), the server sets the robot's pose to the map's ``dock`` waypoint wherever the robot stands:
localization then believes it is at the dock, and every plan starts there. Until the owner
confirms it or sets the pose, ``GET /mode`` (and ``/status``, the ``mode`` events) say so under
``localization``, so a page can ask where the robot is. Pure: no rospy, no Flask.
"""

import datetime

NOT_ASSUMED = {"assumed": False, "from": None, "since": None}


class AssumedPose:
    """The ``localization`` field of the mode: ``{"assumed", "from", "since"}``. Guarded by the manager's lock."""

    def __init__(self):
        self._state = dict(NOT_ASSUMED)

    def assume(self, source):
        """The server set the pose from ``source`` (the waypoint's name, ``dock``), nobody checked it."""
        self._state = {"assumed": True, "from": source, "since": _now_iso()}

    def settle(self):
        """A person set the pose or confirmed it (or a new switch began); True if it was assumed."""
        was = self._state["assumed"]
        self._state = dict(NOT_ASSUMED)
        return was

    def as_dict(self):
        return dict(self._state)


def _now_iso():
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
