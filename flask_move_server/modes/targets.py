"""Where a mode switch goes (:class:`Target`), and where the server goes at start-up without a choice.

Pure: no rospy, no Flask.
"""

from dataclasses import dataclass
from typing import Optional

from flask_move_server.geometry import Pose2D

OUTSIDE = "the navigation stack is started outside this server (modes.stack: none)"
IDLE = "idle: no navigation stack runs; start mapping with POST /mode {\"mode\": \"mapping\"} (robotctl map start)"


@dataclass(frozen=True)
class Target:
    """Where a switch goes: the mode, its map (name and yaml; None: the stack's own), the pose to set."""

    mode: str
    map: Optional[str] = None
    yaml: Optional[str] = None
    pose: Optional[Pose2D] = None
    note: Optional[str] = None  # the message once running, when the mode has something to say

    def describe(self):
        if self.mode == "navigation":
            return "navigation on the map {!r}".format(self.map) if self.map else "navigation on the stack's own map"
        return self.mode


def default_target(stack_kind):
    """Nothing remembered: ``--sim`` navigates on its own map (as it always did); a robot waits idle."""
    if stack_kind == "sim":
        return Target("navigation")
    return Target("idle", note=IDLE)


def unusable_map_target(name, why):
    """The remembered map cannot be used (``why``: it is gone, its name is bad): idle, saying what to do."""
    return Target("idle", note="idle: the map {!r} used before the restart {}; GET /maps lists the saved maps, "
                               "POST /mode {{\"mode\": \"navigation\", \"map\": NAME}} uses one".format(name, why))
