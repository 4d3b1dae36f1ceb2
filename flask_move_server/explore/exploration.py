"""One exploration as the API shows it (``GET /explore``'s EXP): its state, its progress, how it ended.

States: ``starting`` (switching to mapping), ``exploring`` (driving to frontiers), ``returning``
(to where it started, or the ``dock`` place marked while mapping), ``saving`` (the map, then the
switch ``then`` asks for), and the ends ``done``, ``failed``, ``canceled`` and ``stuck`` (the robot
could not move: nothing saved, mapping goes on, ``explore/stuck.py``). Pure: no rospy.
"""

import datetime
import time
from dataclasses import dataclass, field
from typing import Optional, Tuple

STARTING, EXPLORING, RETURNING, SAVING = "starting", "exploring", "returning", "saving"
DONE, FAILED, CANCELED, STUCK = "done", "failed", "canceled", "stuck"
ENDED = (DONE, FAILED, CANCELED, STUCK)
THEN = ("navigation", "idle")
MAX_MINUTES = 240.0  # four hours: longer than any flat takes, short enough to catch a typo


def _now_iso():
    return datetime.datetime.now().astimezone().isoformat(timespec="seconds")


@dataclass
class Exploration:
    """What one ``POST /explore`` asked for, and how far it got."""

    save_as: str
    then: str = "navigation"
    max_minutes: float = 30.0
    return_home: bool = True
    overwrite: bool = False
    state: str = STARTING
    message: str = "Starting mapping."
    frontiers: int = 0
    unreachable: int = 0
    known_m2: float = 0.0
    goals: int = 0
    target: Optional[Tuple[float, float]] = None
    map: Optional[str] = None
    started: str = field(default_factory=_now_iso)
    _began: float = field(default_factory=time.monotonic, repr=False)
    _ended_at: Optional[float] = field(default=None, repr=False)

    @property
    def active(self):
        return self.state not in ENDED

    @property
    def elapsed(self):
        """Seconds since it began, frozen once it ended."""
        return (self._ended_at if self._ended_at is not None else time.monotonic()) - self._began

    def over_time(self):
        """True once ``max_minutes`` have passed."""
        return self.elapsed >= self.max_minutes * 60.0

    def end(self, state, message):
        self.state, self.message, self.target = state, message, None
        self._ended_at = time.monotonic()

    def as_dict(self):
        return {
            "state": self.state, "message": self.message,
            "frontiers": self.frontiers, "unreachable": self.unreachable,
            "known_m2": round(self.known_m2, 1), "goals": self.goals,
            "elapsed": round(self.elapsed, 1),
            "target": [round(v, 2) for v in self.target] if self.target is not None else None,
            "map": self.map, "save_as": self.save_as, "then": self.then,
            "max_minutes": self.max_minutes, "return_home": self.return_home, "started": self.started,
        }
