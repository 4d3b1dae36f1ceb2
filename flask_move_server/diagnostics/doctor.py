"""The doctor: one report of every check, for ``GET /diagnostics``, ``robotctl doctor`` and the Health panel.

It listens to ROS for a short window (``diagnostics.window`` seconds, or what the caller asks),
reads the Pi's own state, and runs the pure checks over both. One examination at a time: a
second caller waits for the first to finish instead of doubling the subscribers.
"""

import threading
import time

from flask_move_server.diagnostics import host
from flask_move_server.diagnostics.checks import overall, ros_checks


class Doctor:
    """Examines the robot on request; holds no state between examinations."""

    def __init__(self, observer, modes, maps_folder, window=2.0, host_root="/"):
        self._observer = observer
        self._modes = modes
        self._maps_folder = maps_folder
        self.window = window
        self._host_root = host_root
        self._lock = threading.Lock()

    def examine(self, seconds=None, box=False):
        """The report: overall status, then each check's name, level, summary and advice."""
        seconds = self.window if seconds is None else seconds
        with self._lock:
            mode = self._modes.status()["mode"] if self._modes is not None and self._modes.runs_stack else None
            observations = self._observer.observe(seconds, mode)
            checks = ros_checks(observations, box)
            checks += host.host_checks(host.read(self._maps_folder, self._host_root))
        return {"status": overall(checks), "mode": mode, "window": seconds,
                "at": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "checks": [c.as_dict() for c in checks]}
