"""The doctor: one report of every check, for ``GET /diagnostics``, ``robotctl doctor`` and the Health panel.

It listens to ROS for a short window (``diagnostics.window`` seconds, or what the caller asks),
reads the Pi's own state, and runs the pure checks over both. One examination at a time: a caller
asking for the same one while it runs (the page and robotctl at once) shares its report; one
asking for another is refused (``DiagnosticsBusy``, 409) rather than queued, so requests never
pile up holding the server's workers for seconds each.
"""

import threading
import time

from flask_move_server.core.errors import DiagnosticsBusy
from flask_move_server.diagnostics import host
from flask_move_server.diagnostics.checks import overall, ros_checks


class _Examination:
    """One examination under way: what it was asked, and its report once done."""

    def __init__(self, key):
        self.key = key
        self.done = threading.Event()
        self.report = None


class Doctor:
    """Examines the robot on request; holds no state between examinations."""

    def __init__(self, observer, modes, maps_folder, window=2.0, host_root="/", simulated=False):
        self._observer = observer
        self._modes = modes
        self._maps_folder = maps_folder
        self.window = window
        self._host_root = host_root
        self._simulated = simulated
        self._lock = threading.Lock()
        self._running = None
        self._more = []  # callables giving more checks: parts built after the doctor (MQTT)

    def add_checks(self, checks):
        """Run ``checks()`` (a list of Check) in every examination too, after the robot's own."""
        self._more.append(checks)

    def examine(self, seconds=None, box=False):
        """The report: overall status, then each check's name, level, summary and advice."""
        seconds = self.window if seconds is None else seconds
        with self._lock:
            running = self._running
            if running is None:
                running = self._running = _Examination((seconds, box))
                mine = True
            elif running.key == (seconds, box):
                mine = False
            else:
                raise DiagnosticsBusy("The robot is already running its checks (for {:g} s{}); try again in a "
                                      "moment.".format(running.key[0], ", with the box test" if running.key[1] else ""))
        if mine:
            try:
                running.report = self._examine(seconds, box)
            finally:
                with self._lock:
                    self._running = None
                running.done.set()
        running.done.wait()
        if running.report is None:
            raise DiagnosticsBusy("The checks that were running failed; try again.")
        return running.report

    def _examine(self, seconds, box):
        mode = self._modes.status()["mode"] if self._modes is not None and self._modes.runs_stack else None
        checks = ros_checks(self._observer.observe(seconds, mode), box, self._simulated)
        checks += host.host_checks(host.read(self._maps_folder, self._host_root))
        for more in self._more:
            checks += more()
        return {"status": overall(checks), "mode": mode, "window": seconds,
                "at": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "checks": [c.as_dict() for c in checks]}
