"""Docking: home to the charger, onto it, and off again; one state machine. No rospy.

``POST /dock`` (the page's Home, Home Assistant's Dock, ``robotctl dock``) starts a worker of its
own: ``going`` (move_base to the staging pose before the dock, ``approach.py``), ``approaching``
(the server drives the last ``staging_distance`` itself, slowly and straight onto the dock's line,
on the teleop topic as ``by: dock``), then confirms: ``charging`` when the battery says CHARGING,
``docked`` when it says FULL, or, with no charging signal (``dock.charge_detect: none``, or no
battery heard), ``docked`` unconfirmed when localization puts it on the dock. A miss (the charger
silent) backs straight off to the staging pose and tries again, ``dock.retries`` tries in all, then
``failed`` there, with the reason, never on top of the charger. ``POST /undock`` (and any goal, run
or exploration while docked: :meth:`Docking.before_goal`) backs straight off to the staging pose.

Any other command (``/stop``, the e-stop, a goal, the joystick) ends a docking under way
(:meth:`Docking.ended_by`); the joystick driving off the charger ends ``docked``. Each change is a
``dock`` event. The states and the words are the owner's (docs/docking.md).
"""

import logging
import threading
import time

from flask_move_server.core.errors import BatteryCritical, DockFailed, NoDock
from flask_move_server.core.geometry import Goal, Pose2D
from flask_move_server.dock.approach import Approach, offset, staging_pose, within

log = logging.getLogger(__name__)

UNDOCKED, GOING, APPROACHING, DOCKED, CHARGING, UNDOCKING, FAILED = (
    "undocked", "going", "approaching", "docked", "charging", "undocking", "failed")
STATES = (UNDOCKED, GOING, APPROACHING, DOCKED, CHARGING, UNDOCKING, FAILED)
ON_THE_DOCK = (DOCKED, CHARGING)
UNDER_WAY = (GOING, APPROACHING, UNDOCKING)
PERIOD = 0.1  # s between two velocity commands of the approach
CONFIRM = 3.0  # s the charger has to say it charges once the robot stands on the dock
WATCH = 1.0  # s between two looks at the charger while docked
SLACK = 2.0  # the time allowed for a straight drive: this many times distance / speed, plus GET_GOING
GET_GOING = 3.0
BACK_SPEED = 2.0  # undocking: this many times the approach speed (at most 0.1 m/s)
NEAR = 0.01  # m: an undocking this near the staging distance is there

SAID = {
    GOING: "Going home to {place}.",
    APPROACHING: "Driving onto the charger at {place} slowly (try {tries} of {of}).",
    CHARGING: "Charging at {place}.",
    DOCKED: "On the charger at {place}: the battery is full.",
    UNDOCKING: "Backing off the charger at {place}.",
}
UNCONFIRMED = "On the charger at {place} (not confirmed: this robot cannot say whether it charges)."
NOT_CHARGING = "On the charger at {place}, but it does not charge: are the contacts clean and the charger on?"
MISSED = "Missed the charger at {place} (try {tries} of {of}): {why}; backing off to try again."
GAVE_UP = "Could not dock at {place}: {why} ({tries} tries). The robot waits in front of the charger."
SILENT = "the battery never said it charges"
OFF_THE_LINE = "it stood {cm:.0f} cm beside the charger or turned {deg:.0f}° off it"
BLOCKED = "something stands before the charger"
UNREACHED = "could not reach the charger's front: {why}"
NOT_THERE = "it did not get there in time"
UNDOCKED_SAID = "Off the charger at {place}."
NOT_DOCKED = "The robot is not on a charger: there is nothing to back off."
CRITICAL = ("The battery is at {:.0f} %, below dock.critical_below ({:.0f} %): the robot only goes home now "
            "(POST /dock, the page's Home). Charge it first.")


class Docking:
    """The robot's dock state (``/status`` ``dock``; ``dock`` events) and the worker driving it."""

    def __init__(self, robot, config, place, charge, events=None, room_ahead=None, level=None, clock=time.monotonic):
        """``robot``: the facade; ``config``: config.DockConfig; ``place()``: the active map's dock (a
        Waypoint) or None; ``charge()``: ``"charging"``, ``"full"``, ``"off"`` or None (nothing says: no
        battery heard, or ``charge_detect: none``); ``events``: the bus; ``room_ahead(reach)``: metres clear
        before the robot (the laser), or None when it cannot say; ``level()``: the battery's charge, 0..1,
        or None when unknown (below ``critical_below`` goals other than home are refused)."""
        self._robot, self.config = robot, config
        self._place, self._charge, self._level = place, charge, level or (lambda: None)
        self._events, self._room_ahead, self._clock = events, room_ahead or (lambda reach: None), clock
        self._lock = threading.Condition()
        self._telling = threading.Lock()  # events in the order of the changes
        # held while the worker checks it may go on and commands motion; re-entrant: the e-stop latched as the
        # staging goal is sent stops the robot from within that send (Robot._unless_latched_meanwhile → ended_by)
        self._sending = threading.RLock()
        self._closed = threading.Event()
        self._job = 0  # bumped by every command: a worker of an older job stops
        self._state, self._name, self._tries, self._confirmed, self._message = UNDOCKED, None, 0, False, None
        self._dock = None  # the dock's Pose2D while docking or docked
        if events is not None:
            events.publish("dock", self._status())  # a stream opened now hears the state first

    # what the server shows -----------------------------------------------------------------

    def status(self):
        """``/status`` ``dock``: ``{"state", "place", "tries", "confirmed", "message"}``."""
        with self._lock:
            return self._status()

    def _status(self):
        return {"state": self._state, "place": self._name, "tries": self._tries, "confirmed": self._confirmed,
                "message": self._message}

    def place(self):
        """The active map's dock (a Waypoint), or None without one."""
        return self._place()

    @property
    def docked(self):
        with self._lock:
            return self._state in ON_THE_DOCK

    def _change(self, job, state, message, tries=None, confirmed=False):
        """A new state, told as a ``dock`` event; only while ``job`` is the current one (None: any). True when
        changed."""
        with self._telling:
            with self._lock:
                if job is not None and job != self._job:
                    return False
                if (state, message) == (self._state, self._message) and confirmed == self._confirmed:
                    return True
                self._state, self._message, self._confirmed = state, message, confirmed
                self._tries = self._tries if tries is None else tries
                told = self._status()
                self._lock.notify_all()
            log.info("dock: %s: %s", state, message)
            if self._events is not None:
                self._events.publish("dock", told)
        return True

    def _said(self, template, tries=None, **more):
        return template.format(place=self._name, tries=tries or self._tries, of=self.config.retries, **more)

    # the owner's commands ---------------------------------------------------------------------

    def dock(self, why=None, keep_run=False):
        """Home to the charger and onto it (``POST /dock``): the status. NoDock when the map has none;
        EStopLatched while the e-stop is on. Docked or docking already: nothing new. ``why``: said before
        "going home" (the battery running low); ``keep_run``: a run paused for it stays paused (the goal
        and teleop end, an exploration ends), else whatever the robot does ends."""
        self._robot.refuse_motion("docking is")
        waypoint = self._place()
        if waypoint is None:
            raise NoDock()
        with self._lock:
            if self._state in ON_THE_DOCK + (GOING, APPROACHING):
                return self._status()
        self._robot.check_zones(staging_pose(waypoint, self.config.staging_distance), waypoint.name)
        going = SAID[GOING].format(place=waypoint.name)
        if keep_run:
            self._robot.halt_for(why or going)
        else:
            self._robot.stop("Going home to {} (POST /dock).".format(waypoint.name))  # ends a run, a goal, teleop
        job = self._next_job(waypoint)
        self._change(job, GOING, "{} {}".format(why, going[0].lower() + going[1:]) if why else going, tries=1)
        self._start(self._go_home, job)
        return self.status()

    def undock(self):
        """Back straight off the charger to the staging pose (``POST /undock``): the status at once.
        DockFailed when the robot is not on a charger."""
        self._robot.refuse_motion("undocking is")
        with self._lock:
            if self._state not in ON_THE_DOCK:
                raise DockFailed(NOT_DOCKED)
            job = self._job = self._job + 1
        self._start(self._back_off_alone, job)
        return self.status()

    def before_goal(self):
        """``Robot._send``: a goal while docked backs off the charger first (waits for it). DockFailed when
        the robot could not get off it (someone stopped it, the e-stop); BatteryCritical below
        ``dock.critical_below``: only going home is taken then."""
        level = self._level()
        if level is not None and level < self.config.critical_below:
            raise BatteryCritical(CRITICAL.format(level * 100, self.config.critical_below * 100))
        with self._lock:
            if self._state not in ON_THE_DOCK:
                return
            job = self._job = self._job + 1
        if not self._back_off(job):
            raise DockFailed("The robot could not back off its charger first: {}".format(
                self.status()["message"] or "it was stopped"))

    def ended_by(self, reason):
        """Someone else commands the robot (``Robot._end_run``): a docking under way ends with ``reason``."""
        with self._sending:  # a command the worker is sending goes first, and is replaced
            with self._lock:
                if self._state not in UNDER_WAY:
                    return
                job = self._job = self._job + 1
        self._change(job, UNDOCKED, reason)

    def driven_off(self):
        """The joystick (``Robot.teleop``): a robot on its charger is driven off it by its owner."""
        with self._lock:
            if self._state not in ON_THE_DOCK + (FAILED,):
                return
            job = self._job = self._job + 1
        self._change(job, UNDOCKED, "Driven off the charger by joystick.")

    def wait(self, timeout):
        """Wait up to ``timeout`` s for a docking to end: True when on the charger, False while under way;
        DockFailed when it failed or ended otherwise."""
        deadline = self._clock() + timeout
        with self._lock:
            while self._state in (GOING, APPROACHING) and not self._closed.is_set():
                left = deadline - self._clock()
                if left <= 0:
                    return False
                self._lock.wait(min(left, 0.5))
            state, message = self._state, self._message
        if state in ON_THE_DOCK:
            return True
        raise DockFailed(message or "The docking ended.")

    def wait_off(self, timeout):
        """Wait up to ``timeout`` s for an undocking to end: True when off the charger (``undocked``)."""
        deadline = self._clock() + timeout
        with self._lock:
            while self._state == UNDOCKING and not self._closed.is_set():
                left = deadline - self._clock()
                if left <= 0:
                    break
                self._lock.wait(min(left, 0.5))
            return self._state == UNDOCKED

    def close(self):
        """Stop a docking under way (the server is stopping). Idempotent."""
        self._closed.set()
        with self._lock:
            self._job += 1
            self._lock.notify_all()

    # the worker ------------------------------------------------------------------------------

    def _next_job(self, waypoint):
        with self._lock:
            self._job += 1
            self._name, self._tries = waypoint.name, 1
            self._dock = Pose2D(waypoint.x, waypoint.y, waypoint.yaw)
            return self._job

    def _start(self, work, job):
        def run():
            try:
                work(job)
            except Exception as exc:  # a worker must end what it started, whatever went wrong
                log.exception("docking failed")
                self._robot.teleop_control.end_command()
                self._change(job, FAILED, self._said(GAVE_UP, why=str(exc)))
        threading.Thread(target=run, name="docking", daemon=True).start()

    def _ours(self, job):
        return job == self._job and not self._closed.is_set() and not self._robot.estop.latched

    def _go_home(self, job):
        """Move_base to the staging pose, then onto the dock, ``retries`` tries; then watch the charger."""
        staging = staging_pose(self._dock, self.config.staging_distance)
        why = self._to_staging(job, staging)
        if why is not None:
            return self._change(job, FAILED, self._said(GAVE_UP, why=UNREACHED.format(why=why)))
        for tries in range(1, self.config.retries + 1):
            if not self._change(job, APPROACHING, self._said(SAID[APPROACHING], tries), tries=tries):
                return None
            why = self._drive_on(job)
            if why is None:
                return self._watch_charger(job) if self._on_it(job) else None
            if why is False:  # someone else took over
                return None
            last = tries == self.config.retries
            message = self._said(GAVE_UP if last else MISSED, tries, why=why)
            log.warning("dock: %s", message)
            if not self._change(job, APPROACHING, message) or not self._back_off(job, then=None):
                return None
        return self._change(job, FAILED, self._said(GAVE_UP, why=why))

    def _to_staging(self, job, staging):
        """Move_base to ``staging``: None when there, else why not (False: someone else took over)."""
        with self._sending:
            if not self._ours(job):
                return False
            seq = self._robot.dock_goal(Goal(staging, None))
        while True:
            state, why = self._robot.goal_end(seq, 0.5)
            if not self._ours(job):
                return False
            if state == "succeeded":
                return None
            if state != "active":
                return why or state

    def _drive_on(self, job):
        """Onto the dock along its line: None when the charger says it charges or the robot stands there, a
        miss's reason, or False when someone else took over."""
        approach = Approach(self._dock, self.config.approach_speed)
        allowed = SLACK * self.config.staging_distance / self.config.approach_speed + GET_GOING
        started = self._clock()
        try:
            while self._clock() - started < allowed:
                if self._charge() == "charging":
                    return None
                pose = self._believed()
                step = approach.step(pose) if pose is not None else (0.0, 0.0)
                if step is None:
                    return self._confirm(job)
                room = self._room_ahead(approach.remaining(pose)) if pose is not None else None
                if room is not None and room + 0.05 < approach.remaining(pose):
                    return BLOCKED
                if not self._command(job, *step):
                    return False
                self._closed.wait(PERIOD)
            return NOT_THERE
        finally:
            self._robot.teleop_control.end_command()

    def _confirm(self, job):
        """Standing where the dock is: None when the charger says so (or the robot cannot say, and stands
        within tolerance), else the miss's reason."""
        self._robot.teleop_control.end_command()
        deadline = self._clock() + CONFIRM
        while self._clock() < deadline:
            charge = self._charge()
            if charge in ("charging", "full"):
                return None
            if charge is None:
                pose = self._believed()
                if pose is not None and within(self._dock, pose):
                    return None
                off = offset(self._dock, pose) if pose is not None else None
                return OFF_THE_LINE.format(cm=abs(off.beside) * 100 if off else 0, deg=abs(off.yaw) * 57.3 if off
                                           else 0)
            if not self._ours(job):
                return False
            self._closed.wait(PERIOD)
        return SILENT

    def _on_it(self, job):
        """Docked: told as the charger says (charging, full, or unconfirmed)."""
        return self._change(job, *self._on_charger_now())

    def _on_charger_now(self):
        charge = self._charge()
        if charge == "charging":
            return CHARGING, self._said(SAID[CHARGING]), None, True
        if charge == "full":
            return DOCKED, self._said(SAID[DOCKED]), None, True
        if charge is None:
            return DOCKED, self._said(UNCONFIRMED), None, False
        return DOCKED, self._said(NOT_CHARGING), None, False

    def _watch_charger(self, job):
        """While docked: charging, full, or not charging as the battery says, until another command."""
        while not self._closed.wait(WATCH):
            with self._lock:
                if job != self._job or self._state not in ON_THE_DOCK:
                    return
            self._change(job, *self._on_charger_now())

    def _back_off_alone(self, job):
        if self._back_off(job):
            self._change(job, UNDOCKED, self._said(UNDOCKED_SAID))

    def _back_off(self, job, then=UNDOCKED):
        """Straight back to the staging distance: True when there (``then``: the state said there, None: none)."""
        if then is not None and not self._change(job, UNDOCKING, self._said(SAID[UNDOCKING])):
            return False
        speed = min(BACK_SPEED * self.config.approach_speed, 0.1)
        approach = Approach(self._dock, speed)
        allowed, started = SLACK * self.config.staging_distance / speed + GET_GOING, self._clock()
        self._robot.drive.rearm()
        try:
            while self._clock() - started < allowed:
                pose = self._believed()
                if pose is not None and approach.remaining(pose) >= self.config.staging_distance - NEAR:
                    break
                if not self._command(job, -speed, 0.0):
                    return False
                self._closed.wait(PERIOD)
        finally:
            self._robot.teleop_control.end_command()
        if then is not None:
            self._change(job, then, self._said(UNDOCKED_SAID))
        return self._ours(job)

    def _command(self, job, linear, angular):
        """One velocity command of the worker, unless someone else took over: True when sent."""
        with self._sending:
            if not self._ours(job):
                return False
            self._robot.teleop_control.command(linear, angular, by="dock")
        return True

    def _believed(self):
        reading = self._robot.pose.current()
        return reading.pose if reading is not None else None
