"""A fleet manager's ``startCharging`` and ``stopCharging`` (VDA 5050 2.0.0, section 6.8.2) on the dock.

``startCharging`` docks onto the active map's charger (``dock/docking.py``, as ``POST /dock``):
RUNNING while it goes home and approaches, FINISHED once it charges (or is docked), FAILED with the
robot's words when it has no dock or gives up. ``stopCharging`` backs off the charger (``POST
/undock``): RUNNING, FINISHED once off; FAILED when it is not on one. Each waits in a thread of its
own: the MQTT thread that brought it goes on. ``batteryState.charging`` is the battery's own word.
"""

import threading

from flask_move_server.core.errors import MoveServerError

WAIT = 600.0  # s a docking is followed at most
REPORTED = object()  # the action reports its own end (instant.py's)


class Charging:
    """startCharging / stopCharging over ``robot`` (the facade), told to ``report`` (report.py)."""

    def __init__(self, robot, report):
        self._robot, self._report = robot, report

    def start(self, action):
        self._robot.dock()  # NoDock, EStopLatched: the action FAILS saying so
        self._report.action(action, "RUNNING", "Going home to the charger.")
        self._follow(action, self._docked)
        return REPORTED

    def stop(self, action):
        self._robot.undock()  # DockFailed when not on a charger
        self._report.action(action, "RUNNING", "Backing off the charger.")
        self._follow(action, self._undocked)
        return REPORTED

    def _follow(self, action, until):
        threading.Thread(target=until, args=(action,), name="vda5050-charging", daemon=True).start()

    def _docked(self, action):
        try:
            self._robot.docking.wait(WAIT)
        except MoveServerError as exc:
            self._report.action(action, "FAILED", str(exc))
            return
        self._report.action(action, "FINISHED", self._robot.dock_status()["message"])

    def _undocked(self, action):
        docking = self._robot.docking
        if docking.wait_off(WAIT):
            self._report.action(action, "FINISHED", "Off the charger.")
        else:
            self._report.action(action, "FAILED", docking.status()["message"] or "It did not get off the charger.")
