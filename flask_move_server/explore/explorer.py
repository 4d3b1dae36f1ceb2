"""The explorer: "map my flat" in one request. Mapping, frontiers, back home, save, navigate.

``start`` checks everything that can be checked before the robot moves (the e-stop, a run or
another exploration under way, the name to save as: taken without ``overwrite`` is a 409), then a
worker thread (``explorer``, its loop explorer_worker.py) does the rest:

1. ``starting``: switch to mapping unless mapping runs already (the mode manager starts the
   stack: SLAM and move_base configured for a growing map, ``launch/mapping.launch``).
2. ``exploring``: on each new map (and each goal's end), ``frontiers.survey`` finds the frontiers
   reachable from the robot over known free space; the best is sent as a move_base goal through
   the Robot facade (``run_goto``: it ends no run and no exploration). A goal is kept while its
   frontier is still there; once the frontier is seen (the map grew there) the next best is sent,
   replacing it (our own preemption: nothing is blacklisted). A goal move_base aborts, or one that
   brings the robot no nearer for ``progress_timeout`` s, blacklists its target; a reached target
   too (what is left of a frontier there cannot be seen from there). It ends when no reachable
   frontier is left twice in a row, or after ``max_minutes``.
3. ``returning``: to where it started, or to the place named ``dock`` marked while mapping.
4. ``saving``: the map through the map service as ``save_as``, then navigation on it (relocalized
   where the robot stands: the saved map keeps the mapping's frame) or idle, as ``then`` says.

Whoever else commands the robot ends it ``canceled`` (the facade calls :meth:`cancel`): ``/stop``,
the e-stop, a ``/goto``, ``/teleop``, a mode switch. The map made so far stays, unsaved, in
mapping mode. Each change is an ``explore`` event (progress at most once a second). Pure: no
rospy, no Flask.
"""

import contextlib
import logging
import threading
import time

from flask_move_server.core.errors import ExploreConflict
from flask_move_server.explore.exploration import (
    CANCELED,
    FAILED,
    SAVING,
    STARTING,
    Exploration,
)
from flask_move_server.explore.explorer_worker import ExplorerWorker

log = logging.getLogger(__name__)

PROGRESS_EVENTS = 1.0  # s between progress events


class Explorer(ExplorerWorker):
    """One exploration at a time, driven over the facade, the mode manager and the map service."""

    def __init__(self, robot, modes, maps, radius, events=None, progress_timeout=30.0, start_timeout=60.0,
                 return_timeout=300.0):
        self._robot = robot
        self._modes = modes
        self._maps = maps
        self.radius = radius
        self._events = events
        self.progress_timeout = progress_timeout
        self.start_timeout = start_timeout
        self.return_timeout = return_timeout
        self._lock = threading.Condition()
        self._sending = threading.RLock()  # held while a goal is sent; a /goto's cancel waits for it
        self._exp = None
        self._worker = None
        self._closed = False
        self._announced = 0.0
        self._home = None  # where the exploration under way began (map frame)
        self._seq = None  # the goal the explorer sent last
        modes.when_leaving_running(self._leaving_mode)

    # asking --------------------------------------------------------------------------------

    def current(self):
        """EXP of the exploration under way or the last one; None before the first."""
        with self._lock:
            return self._exp.as_dict() if self._exp is not None else None

    def start(self, save_as, then="navigation", max_minutes=30.0, return_home=True, overwrite=False):
        """Start exploring; EXP at once. Refused before anything moves: the e-stop, a run or an
        exploration under way, a map name taken (MapExists unless ``overwrite``), no stack to run."""
        name = self._maps.check_new_name(save_as, overwrite)
        self._refuse_without_stack()
        with self._lock:
            self._refuse_start()
        self._begin_mapping()  # not under our lock: the mode manager calls _leaving_mode under its own
        with self._lock:
            self._refuse_start()
            exp = Exploration(name, then, float(max_minutes), bool(return_home), bool(overwrite))
            self._exp = exp
            self._worker = threading.Thread(target=self._work, args=(exp,), name="explorer", daemon=True)
            self._worker.start()
            self._changed(exp)
            return exp.as_dict()

    def _begin_mapping(self):
        """Switch to mapping unless it runs or is starting (ModeSwitching while another switch is under way)."""
        status = self._modes.status()
        if status["mode"] != "mapping" or status["state"] == "failed":
            self._modes.switch("mapping")

    def _refuse_without_stack(self):
        if not self._modes.runs_stack:
            raise ExploreConflict("This server does not run the navigation stack (modes.stack: none), so it "
                                  "cannot start mapping to explore; start your mapping launch file and drive "
                                  "the robot with the joystick.")

    def _refuse_start(self):
        """Lock held: why no exploration may start now, raised."""
        if self._closed or self._robot.shutting_down:
            raise ExploreConflict("The server is shutting down: no exploration starts now.")
        self._robot.refuse_motion("exploring is")
        if self._exp is not None and self._exp.active:
            raise ExploreConflict("The robot is already exploring (to save as {!r}): stop it first (POST /stop), "
                                  "or wait until it is done (GET /explore).".format(self._exp.save_as))
        runs = self._robot.runs
        active = runs.active() if runs is not None else None
        if active is not None:
            raise ExploreConflict("Run {} ({}) is under way: cancel it first (POST /runs/{}/cancel).".format(
                active["id"], active.get("route") or "unnamed", active["id"]))

    def cancel(self, reason, wait_for_send=True):
        """Someone else commands the robot (or stops it): the exploration under way ends ``canceled``,
        saying ``reason``; True if one was. The robot's goal is the caller's to stop (``Robot.stop``).

        ``wait_for_send``: for a command about to send motion of its own, so that a goal the explorer
        is sending goes first and is replaced, never the other way round."""
        with self._sending if wait_for_send else contextlib.nullcontext():
            with self._lock:
                exp = self._exp
                if exp is None or not exp.active or exp.state == SAVING:
                    return False
                self._end(exp, CANCELED, "{} The map made so far stays in mapping mode, unsaved: save it "
                          "(POST /maps) or explore again.".format(reason.rstrip(".") + "."))
                return True

    def _leaving_mode(self, status):
        """The mode manager leaves a running stack (under its lock): a switch not ours ends exploring."""
        with self._lock:
            exp = self._exp
            if exp is None or not exp.active or exp.state in (STARTING, SAVING):
                return
            self._end(exp, CANCELED, "The robot switched to {}, which ended exploring; the map made so far "
                      "was not saved.".format(status["mode"]))

    def close(self):
        """The server stops: an exploration under way ends ``canceled``; the worker is joined."""
        with self._lock:
            self._closed = True
            exp, worker = self._exp, self._worker
            if exp is not None and exp.active and exp.state != SAVING:
                self._end(exp, CANCELED, "The server stopped while exploring; the map made so far was not saved.")
        if worker is not None and worker is not threading.current_thread():
            worker.join(timeout=5)

    # small parts -----------------------------------------------------------------------------

    def _fail(self, exp, message):
        with self._lock:
            if exp.active and self._exp is exp:
                self._end(exp, FAILED, message)
        return False

    def _end(self, exp, state, message):
        """Lock held: the exploration ends; the event goes out at once."""
        exp.end(state, message)
        log.info("exploration %s: %s", state, message)
        self._changed(exp)
        self._lock.notify_all()

    def _cancel_own_goal(self):
        seq = getattr(self, "_seq", None)
        if seq is not None:
            self._robot.cancel_goal(seq)

    def _changed(self, exp):
        """Lock held: tell the change as an ``explore`` event."""
        self._announced = time.monotonic()
        if self._events is not None:
            self._events.publish("explore", exp.as_dict())

    def _progress(self, exp):
        """Lock held: progress is told at most once a second."""
        if time.monotonic() - self._announced >= PROGRESS_EVENTS:
            self._changed(exp)







