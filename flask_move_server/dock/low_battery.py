"""Going home before empty: below ``dock.return_below`` the robot docks by itself. No rospy.

:class:`LowBattery` looks at the battery's charge every ``PERIOD`` s. Once it falls below
``dock.return_below`` (20 %) it docks (``dock/docking.py``): a run under way is **paused**, not
canceled ("Battery 18 %: gone home to charge; the run goes on by itself at 80 %."), a single goal
or an exploration ends saying why, and the ``low_battery`` happening is told (a webhook). Once
the robot, on its charger, is back at ``dock.resume_above`` (80 %), the run it paused goes on by
itself (its message says so, its closing summary too); a run started meanwhile begins paused and
goes on by itself then too (the run executor asks :meth:`LowBattery.why`). Below ``dock.critical_below`` (10 %) goals
other than home are refused (``Docking.before_goal``).

It leaves alone a robot driven by its owner's joystick (it goes home once they let go), one the
e-stop holds, a map without a dock (said once in the log), and a robot with no battery reading or
no percentage: none of this happens then. One return per fall below the threshold: a docking that
failed is not tried again until the charge has been above ``return_below`` (charged by hand).
"""

import logging
import threading

from flask_move_server.core.errors import MoveServerError

log = logging.getLogger(__name__)

PERIOD = 1.0  # s between two looks at the charge
ON_THE_DOCK = ("docked", "charging")
DOCKING = ("going", "approaching", "undocking")
PAUSED_FOR_IT = "Battery {:.0f} %: gone home to charge; the run goes on by itself at {:.0f} %."
GOING = "Battery {:.0f} %:"
RESUMED = "Charged to {:.0f} % at {}: the run went on by itself."
STARTS_CHARGED = "Battery {:.0f} %: the robot goes home to charge first; the run starts by itself at {:.0f} %."


class LowBattery:
    """Sends the robot home when its battery runs low, and a run it paused on once charged."""

    def __init__(self, robot, docking, runs, config, tell=None):
        """``robot``: the facade (its ``battery_status``, ``teleop_control``, ``estop``); ``docking``: the
        Docking; ``runs``: the run executor, or None; ``config``: config.DockConfig; ``tell(data)``: the
        ``low_battery`` happening (``{"percentage", "place", "run"}``), or None."""
        self._robot, self._docking, self._runs, self.config = robot, docking, runs, config
        self._tell = tell or (lambda data: None)
        self._gone = False  # gone home for this fall below return_below
        self._paused = None  # the id of the run paused to go home
        self._no_dock_said = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="low-battery", daemon=True)

    def start(self):
        self._thread.start()
        return self

    def _run(self):
        while not self._stop.wait(PERIOD):
            try:
                self.look()
            except Exception:  # the robot goes on without it, and the log says why
                log.exception("going home on a low battery failed")

    def look(self):
        """One look at the charge: home when low, the paused run on when charged."""
        level = self._level()
        if level is None:
            return
        state = self._docking.status()["state"]
        if level >= self.config.return_below:
            self._gone = False
        if level < self.config.return_below and not self._gone and state not in ON_THE_DOCK + DOCKING:
            self._go_home(level)
        elif self._paused is not None and state in ON_THE_DOCK and level >= self.config.resume_above:
            self._resume(level)

    # a run started while the robot goes home to charge (the run executor's holds_new_runs) ---------

    def why(self):
        """Why a run started now begins paused (the robot goes home, or charges, below return_below), or None."""
        level = self._level()
        if level is None or level >= self.config.return_below:
            return None
        if self._docking.status()["state"] not in ON_THE_DOCK + ("going", "approaching"):
            return None  # not going home (a docking that failed, the joystick): the run starts as asked
        return STARTS_CHARGED.format(level * 100, self.config.resume_above * 100)

    def held(self, run_id):
        """The run ``why`` held: it goes on by itself at resume_above, as a run paused for the charge."""
        self._paused = run_id

    def _level(self):
        battery = self._robot.battery_status()
        if not battery or battery.get("percentage") is None:
            return None
        return battery["percentage"] / 100.0

    def _go_home(self, level):
        if self._robot.estop.latched or self._robot.teleop_control.status().get("by") == "owner":
            return  # the e-stop holds it, or its owner drives it: home once they let go
        place = self._docking.place()
        if place is None:
            if not self._no_dock_said:
                log.warning("battery %.0f %%: this map has no dock to go home to", level * 100)
            self._no_dock_said = True
            return
        self._gone = True
        run = self._pause_run(level)
        try:
            self._docking.dock(why=GOING.format(level * 100), keep_run=True)
        except MoveServerError as exc:
            log.warning("battery %.0f %%: could not go home: %s", level * 100, exc)
            return
        log.warning("battery %.0f %%: going home to %s%s", level * 100, place.name,
                    ", run {} paused".format(run) if run is not None else "")
        self._tell({"percentage": round(level * 100, 1), "place": place.name, "run": run})

    def _pause_run(self, level):
        """The run under way paused (its id), or None when none runs."""
        run = self._runs.active() if self._runs is not None else None
        if run is None or run["state"] != "running":
            return None
        try:
            self._runs.pause(run["id"], why=PAUSED_FOR_IT.format(level * 100, self.config.resume_above * 100))
        except MoveServerError as exc:
            log.warning("battery %.0f %%: could not pause run %d: %s", level * 100, run["id"], exc)
            return None
        self._paused = run["id"]
        return run["id"]

    def _resume(self, level):
        run_id, self._paused = self._paused, None
        run = self._runs.get(run_id)
        if run["state"] != "paused":
            return  # its owner resumed it, or ended it, meanwhile
        place = self._docking.status()["place"]
        try:
            self._runs.resume(run_id, why=RESUMED.format(level * 100, place))
        except MoveServerError as exc:
            log.warning("charged to %.0f %%: run %d could not go on: %s", level * 100, run_id, exc)
            return
        log.info("charged to %.0f %%: run %d goes on", level * 100, run_id)

    def close(self):
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(2.0)
