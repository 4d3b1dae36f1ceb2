"""The mode manager: which navigation stack runs (idle, mapping, navigation on a map), one switch at a time.

A switch is checked at once (unknown map → UnknownMap before anything is stopped), then runs
in a background thread: the running stack is stopped (state ``stopping``), the new one
started (``starting``), and the mode is ``running`` or ``failed`` with the backend's message.
Every state change is published as a ``mode`` event carrying the ``GET /mode`` body, and a
mode that reached ``running`` is remembered in ``Config.mode_state_file()`` for the next start;
while that file cannot be written, every status's message says so (``unsaved``).

A stack that dies by itself (the backend calls ``on_exit``: ``modes/crashes.py``) is restarted as ``modes/restarts.py``
allows (up to ``modes.restarts`` times, after 1, 2 then 4 s; a long run forgives earlier
crashes), and is ``failed`` after that (what is left of it stopped: roslaunch keeps a stack's
other nodes running when one dies).

The backend (``modes/launched.py`` on the robot, ``modes/simulated.py`` with ``--sim``) does
the work: ``start(mode, map_yaml_or_None, on_exit)`` blocks until the stack is ready or raises
StackFailed; ``stop()`` is idempotent; an optional ``serves_goals(mode)`` says whether the
mode runs move_base (no: "running" does not wait for goals to reach one). ``relocalize(pose)``
publishes the robot's pose estimate (``ros/initial_pose.py``). A dock the server set after a
switch is an assumption (``localization`` in every status, ``assumed_pose.py``) until
``set_pose`` or ``confirm_pose``. Pure: no rospy, no Flask.
"""

import datetime
import functools
import logging
import threading
import time

from flask_move_server.core.errors import ModesOff, ModeSwitching, StackFailed, WrongMode
from flask_move_server.maps.catalogue import MapCatalogue
from flask_move_server.modes import relocalizing, state_file
from flask_move_server.modes.assumed_pose import AssumedPose
from flask_move_server.modes.crashes import StackCrashes
from flask_move_server.modes.restarts import RestartBudget
from flask_move_server.modes.targets import IDLE, OUTSIDE, Target, Targets

log = logging.getLogger(__name__)

MESSAGE_LIMIT = 500  # characters of a mode's message (a stack's failure, a note)

def _now_iso():
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


class ModeManager(StackCrashes):
    """The mode in force and the one switch allowed at a time; ``backend`` None: modes are off."""

    READY_WAIT = 5.0  # seconds a started stack's move_base may take to answer the server's action client
    READY_POLL = 0.05

    def __init__(self, config, backend, events=None, relocalize=None, clock=time.monotonic, goals_ready=None):
        """``relocalize(pose)``: publish a pose estimate; ``goals_ready()``: True once /goto would reach move_base."""
        self._config = config
        self._backend = backend
        self._events = events
        self._relocalize = relocalize
        self._goals_ready = goals_ready
        self.targets = Targets(config, MapCatalogue(config.maps_folder()))
        self._changed = threading.Condition()
        self._busy = False
        self._gen = 0
        self._thread = None
        self._closing = threading.Event()
        self._closed = False
        self._up = False  # the backend may have a stack running (stop it before the next start)
        self.restart_budget = RestartBudget(config.modes, clock)
        self._unsaved = None  # why the last mode could not be remembered, said in every message until one is
        self._assumed = AssumedPose()  # the pose the server set (the dock) and nobody confirmed yet
        # Until restore(): idle with nothing started; without a backend, the outside stack's navigation.
        self._target = Target("idle") if backend else Target("navigation")
        self._status = self._body(self._target, "running", IDLE if backend else OUTSIDE)
        self._leaving_running = []

    # reading ---------------------------------------------------------------

    def status(self):
        """The ``GET /mode`` body: mode, map, state, since, message."""
        with self._changed:
            return dict(self._status)

    def status_and_generation(self):
        """The ``GET /mode`` body and the switch it belongs to (a number that grows with each switch)."""
        with self._changed:
            return dict(self._status), self._gen

    def takes_goals(self, mode):
        """Does ``mode``'s stack run move_base? The backend says (``serves_goals``); if it cannot, assume so."""
        return self._serves_goals(mode)

    def when_leaving_running(self, callback):
        """Call ``callback(status)`` (under the manager's lock: be quick) each time the mode stops running."""
        self._leaving_running.append(callback)

    @property
    def runs_stack(self):
        """True when this server starts and stops the navigation stack (``modes.stack`` is not none)."""
        return self._backend is not None

    @property
    def active_map(self):
        """The named map of the navigation mode in force (or being started); None otherwise."""
        with self._changed:
            return self._target.map if self._target.mode == "navigation" else None

    def wait(self, timeout):
        """Wait up to ``timeout`` s for the switch: True once running, False if still under way; StackFailed."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while self._busy or self._status["state"] not in ("running", "failed"):
                left = deadline - time.monotonic()
                if left <= 0 or self._closed:
                    return False
                self._changed.wait(left)
            if self._status["state"] == "failed":
                raise StackFailed(self._status["message"])
            return True

    # switching -------------------------------------------------------------

    def switch(self, mode, map_name=None, pose=None):
        """Start switching to ``mode`` (navigation: on ``map_name``; None: the stack's own map).

        ``pose``: a Pose2D or a waypoint name on that map, set once navigation runs. Returns the
        ``starting`` status at once; ModesOff, ModeSwitching, UnknownMap, BadRequest refuse.
        """
        if self._backend is None:
            raise ModesOff("This server does not run the navigation stack (modes.stack: none): "
                           "start mapping or navigation with your own launch files.")
        target = self.targets.of(mode, map_name, pose)
        with self._changed:
            if self._busy:
                raise ModeSwitching("A switch to {} is under way; wait for it (GET /mode) and try again."
                                    .format(self._target.describe()))
            self._begin(target, "starting", "starting " + target.describe())
            gen, starting = self._gen, dict(self._status)
        self._spawn(self._switch, gen, target)
        return starting

    def _begin(self, target, state, message):
        """Under the lock: a new switch owns the manager (the old stack's exits are ignored from now on)."""
        self._busy = True
        self._gen += 1
        self._target = target
        self._assumed.settle()  # the next stack's localization starts afresh
        self._set(target, state, message)

    def _spawn(self, work, *args):
        self._thread = threading.Thread(target=work, args=args, name="mode-switch", daemon=True)
        self._thread.start()

    def _switch(self, gen, target):
        try:
            if self._up:
                with self._changed:
                    self._set(target, "stopping", "stopping before " + target.describe())
            self._stop_stack()  # idempotent: also whatever a backend runs before the first switch
            self.restart_budget.renew()
            failure = self._start(gen, target, "starting " + target.describe(), relocalize=True)
            if failure is not None:
                with self._changed:
                    self._set(target, "failed", failure)
                    self._release(gen)
        finally:
            self._done(gen)

    def _start(self, gen, target, message, relocalize):
        """Bring ``target`` up; None when running, else the failure's message (the caller says failed)."""
        with self._changed:
            self._set(target, "starting", message)
        if target.mode == "idle":
            self._running(gen, target, target.note or IDLE)
            return None
        self._up = True
        try:
            self._backend.start(target.mode, target.yaml, functools.partial(self._on_exit, gen))
        except Exception as exc:  # StackFailed says what to fix; anything else is a backend bug, logged
            if not isinstance(exc, StackFailed):
                log.exception("the %s stack could not start", target.mode)
            return str(exc) or type(exc).__name__
        late = self._await_goals() if self._serves_goals(target.mode) else ""
        assumed = None
        if relocalize:
            note, assumed = relocalizing.after_start(target, self.targets.waypoints_path, self._publish_pose)
        else:
            note = relocalizing.restarted_note(target, self.restart_budget.used)
        self._running(gen, target, note + late, assumed)
        return None

    def _serves_goals(self, mode):
        """Does ``mode``'s stack run move_base? The backend says (``serves_goals``); if it cannot, assume so."""
        serves = getattr(self._backend, "serves_goals", None)
        return serves is None or serves(mode)

    def _await_goals(self):
        """Wait briefly until goals reach the new move_base, so "running" means /goto works; a note if not."""
        if self._goals_ready is None:
            return ""
        deadline = time.monotonic() + self.READY_WAIT
        while not self._goals_ready():
            if time.monotonic() >= deadline or self._closing.wait(self.READY_POLL):
                return "; move_base does not answer this server's goals yet (GET /health)"
        return ""

    def _running(self, gen, target, message, assumed=None):
        """Remember ``target`` for the next start, then say it runs (a waiter finds it remembered).

        ``assumed``: the waypoint the server set the pose at, unconfirmed (said with the status).
        """
        unsaved = self._remember(target)
        with self._changed:
            self._unsaved = unsaved
            if assumed is not None and gen == self._gen:
                self._assumed.assume(assumed)
            self.restart_budget.running()
            self._set(target, "running", message)
            self._release(gen)  # in the same breath: a crash from now on is this run's

    def _remember(self, target):
        """Save ``target`` as the mode to come back to; None, or why it could not be (for the messages)."""
        path = self._config.mode_state_file()
        try:
            state_file.save(path, target.mode, target.map)
        except OSError as exc:
            log.warning("cannot remember the mode in %s: %s", path, exc)
            return "not remembered for the next start: cannot write {} ({})".format(path, exc.strerror or exc)
        return None

    def _release(self, gen):
        """Under the lock: switch ``gen`` is over (unless a newer one owns the manager already)."""
        if gen == self._gen:
            self._busy = False
            self._changed.notify_all()

    def _done(self, gen):
        with self._changed:
            self._release(gen)

    def _stop_stack(self):
        try:
            self._backend.stop()
        except Exception:  # stop is best effort; the next start says if something is left
            log.exception("stopping the navigation stack failed")
        self._up = False

    def _set(self, target, state, message):
        """Under the lock: the new status, published as a ``mode`` event."""
        was_running = self._status["state"] == "running"
        self._status = self._body(target, state, message)
        if was_running and state != "running":
            for callback in self._leaving_running:
                callback(dict(self._status))
        self._changed.notify_all()
        if self._events is not None:
            self._events.publish("mode", dict(self._status))

    def _body(self, target, state, message):
        message = _bounded(message)
        if self._unsaved:
            message = "{}; {}".format(message, self._unsaved) if message else self._unsaved
        return {"mode": target.mode, "map": target.shown_map, "state": state, "since": _now_iso(), "message": message,
                "localization": self._assumed.as_dict()}

    # start-up, pose, close -------------------------------------------------

    def restore(self):
        """At start-up: come back to the remembered mode (else the default); never raises."""
        if self._backend is None:
            return
        target = self.targets.remembered(*state_file.load(self._config.mode_state_file()))
        try:
            with self._changed:
                self._begin(target, "starting", "starting " + target.describe())
                gen = self._gen
            self._spawn(self._switch, gen, target)
        except Exception:
            log.exception("cannot restore the mode %s", target.describe())

    def set_pose(self, pose):
        """Tell localization the robot is at ``pose`` (in the map frame); WrongMode unless navigating.

        ModeSwitching while a switch (or a restart) is under way: the localization being started
        would miss the pose or overwrite it with the map's dock, while the answer said ok.
        """
        with self._changed:
            busy, target, gen = self._busy, self._target, self._gen
        if busy:
            raise ModeSwitching("A switch to {} is under way, so a pose now would be lost; wait until GET /mode "
                                "says running, or give the pose with the switch (POST /mode with \"pose\")."
                                .format(target.describe()))
        mode = self.status()["mode"]
        if mode == "idle":
            raise WrongMode("No map is in use (the mode is idle): start navigation on a map first "
                            "(POST /mode {\"mode\": \"navigation\", \"map\": NAME}).")
        if mode == "mapping":
            raise WrongMode("While mapping, the map is built around where the robot started, and SLAM takes "
                            "no pose; save the map, then set the pose when navigating on it.")
        self._publish_pose(pose)
        with self._changed:
            if gen == self._gen:
                self._settle_assumption()

    def confirm_pose(self):
        """The owner says the robot is where localization believes: the assumed pose is settled.

        Returns the ``localization`` status; ModeSwitching while a switch is under way (the pose
        being confirmed is not the one the new stack will believe). Nothing assumed: nothing to do.
        """
        with self._changed:
            if self._busy:
                raise ModeSwitching("A switch to {} is under way: confirm the robot's pose once GET /mode says "
                                    "running.".format(self._target.describe()))
            self._settle_assumption()
            return self._assumed.as_dict()

    def _settle_assumption(self):
        """Under the lock: the pose is the owner's now; the status (and a ``mode`` event) say so if it changed."""
        if not self._assumed.settle():
            return
        self._status = dict(self._status, localization=self._assumed.as_dict())
        self._changed.notify_all()
        if self._events is not None:
            self._events.publish("mode", dict(self._status))

    def _publish_pose(self, pose):
        if self._relocalize is None:
            raise ModesOff("This server cannot publish the robot's pose (no ROS publisher).")
        self._relocalize(pose)

    def close(self):
        """Stop switching, stop the stack, release the backend. Idempotent."""
        with self._changed:
            if self._closed:
                return
            self._closed = True
            self._gen += 1
            self._changed.notify_all()
        self._closing.set()
        thread = self._thread
        if thread is not None:
            thread.join(self._config.modes.stop_timeout)
        if self._backend is not None:
            self._stop_stack()
            close = getattr(self._backend, "close", None)
            if close is not None:
                close()


def _bounded(message, limit=MESSAGE_LIMIT):
    """A status message cut to ``limit`` characters: it goes into every /status, /mode and event.

    A failed start quoted a hostile map file's value whole, and every answer carried 36 MB until
    the next switch.
    """
    if message is None or len(message) <= limit:
        return message
    return message[:limit - 1].rstrip() + "…"
