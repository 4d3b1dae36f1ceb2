"""The explorer: "map my flat" in one request. Mapping, frontiers, back home, save, navigate.

``start`` checks everything that can be checked before the robot moves (the e-stop, a run or
another exploration under way, the name to save as: taken without ``overwrite`` is a 409), then a
worker thread (``explorer``) does the rest:

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
import math
import threading
import time

from flask_move_server.core.errors import ExploreConflict, MoveServerError, NoPose, UnknownWaypoint
from flask_move_server.core.geometry import Goal, Pose2D
from flask_move_server.explore.exploration import (
    CANCELED,
    DONE,
    EXPLORING,
    FAILED,
    RETURNING,
    SAVING,
    STARTING,
    Exploration,
)

log = logging.getLogger(__name__)

POLL = 0.5  # s between looks at the map and the goal (a goal's end wakes the worker at once)
PROGRESS_EVENTS = 1.0  # s between progress events
NEARER = 0.1  # m the robot must come nearer its target within progress_timeout
KEEP = 0.75  # m: a goal is kept while a frontier's target lies this near it
DOCK = "dock"
HOME_TRIES = 2  # goals home before the map is saved where the robot stands


class Explorer:
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

    # the worker ------------------------------------------------------------------------------

    def _work(self, exp):
        try:
            if self._to_mapping(exp) and self._explore(exp) and self._go_home(exp):
                self._save(exp)
        except Exception as exc:  # a worker must end its exploration, whatever went wrong
            log.exception("exploring failed")
            with self._lock:
                if exp.active:
                    self._end(exp, FAILED, "Exploring failed: {}".format(exc))
        finally:
            with self._lock:
                exp.target = None
            self._cancel_own_goal()

    def _still(self, exp):
        with self._lock:
            return exp.active and self._exp is exp and not self._closed

    def _to_mapping(self, exp):
        """Mapping runs (switched to if needed); False when the exploration ended meanwhile."""
        if not self._modes.wait(self.start_timeout):
            return self._fail(exp, "Mapping did not start within {:g} s (GET /mode says why).".format(
                self.start_timeout))
        self._maps.source.latest(self._maps.save_timeout)  # the first map: the first survey needs one
        home = self._first_pose(exp)
        with self._lock:
            if home is None or not self._still(exp):
                return False
            exp.state, exp.message = EXPLORING, "Looking for the edges of what the robot has seen."
            self._home = home
            self._changed(exp)
        return True

    def _first_pose(self, exp):
        """Where the robot stands on the new map, waiting for SLAM's first tf (None: ended or failed)."""
        deadline = time.monotonic() + self._maps.save_timeout
        while self._still(exp):
            try:
                return self._robot.current_pose()
            except NoPose as exc:
                if time.monotonic() > deadline:
                    self._fail(exp, "The robot's place on the new map is not known: {}".format(exc))
                    return None
            time.sleep(POLL / 5)
        return None

    def _explore(self, exp):
        """Drive to frontiers until none is left or time is up; False when the exploration ended."""
        blacklist, goal = [], None
        empty = 0
        while self._still(exp):
            if goal is not None:
                goal = self._follow(goal, blacklist)
            survey = self._survey(exp, blacklist)
            if goal is not None and survey is not None and not _still_there(goal, survey):
                goal = None  # its frontier was seen: the next goal replaces this one (no cancel, no blacklist)
            if goal is None and survey is not None:
                if not survey.frontiers:
                    empty += 1
                    if empty >= 2:
                        return self._explored(exp, survey)
                    time.sleep(POLL)
                    continue
                empty = 0
                goal = self._send(exp, survey.frontiers[0].target)
            if exp.over_time():
                self._cancel_own_goal()
                with self._lock:
                    exp.message = "Stopped exploring after {:g} minutes, as asked; {} frontiers were left.".format(
                        exp.max_minutes, exp.frontiers)
                return self._still(exp)
            if goal is not None:
                goal.wait(self._robot, POLL)
        return False

    def _survey(self, exp, blacklist):
        """The frontiers on the latest map from where the robot stands (None: no pose or map now)."""
        from flask_move_server.explore import frontiers  # numpy: loaded by the first exploration, not at rest

        try:
            _, grid = self._maps.source.current()
            pose = self._robot.current_pose()
        except (MoveServerError, NoPose) as exc:
            log.info("explorer: no map or pose now (%s)", exc)
            time.sleep(POLL)
            return None
        survey = frontiers.survey(grid, (pose.x, pose.y), self.radius, blacklist=blacklist)
        with self._lock:
            exp.frontiers, exp.unreachable = len(survey.frontiers), len(survey.unreachable)
            exp.known_m2 = survey.known_m2
            self._progress(exp)
        return survey

    def _follow(self, goal, blacklist):
        """The goal under way after a look: kept, or ended (None; its target blacklisted unless replaced by us)."""
        state, why = self._robot.goal_end(goal.seq, 0)
        if state == "succeeded":
            blacklist.append(goal.target)
            return None
        if state not in ("active", "canceling"):
            if state != "preempted":
                log.info("explorer: frontier at (%.2f, %.2f) given up: %s %s", *goal.target, state, why or "")
                blacklist.append(goal.target)
            return None
        if goal.stalled(self._robot, self.progress_timeout):
            log.info("explorer: no progress toward (%.2f, %.2f) for %g s", *goal.target, self.progress_timeout)
            blacklist.append(goal.target)
            self._robot.cancel_goal(goal.seq)
            return None
        return goal

    def _send(self, exp, target):
        """Send a goal to ``target`` facing away from the robot; the _Goal, or None when refused or ended."""
        with self._sending:
            if not self._still(exp):
                return None
            try:
                here = self._robot.current_pose()
                yaw = math.atan2(target[1] - here.y, target[0] - here.x)
                seq = self._robot.run_goto(Goal(Pose2D(target[0], target[1], yaw), None))
            except MoveServerError as exc:
                self._fail(exp, "A goal to the next frontier was refused: {}".format(exc))
                return None
            with self._lock:
                if not self._still(exp):  # a stop came as it was sent: this goal is ours to cancel
                    self._robot.cancel_goal(seq)
                    return None
                exp.goals += 1
                exp.target = target
                self._seq = seq
                self._changed(exp)
        return _Goal(seq, target, here.distance_to(Pose2D(target[0], target[1], 0.0)))

    def _explored(self, exp, survey):
        with self._lock:
            if not self._still(exp):
                return False
            unreachable = len(survey.unreachable)
            exp.message = "The whole reachable flat is mapped ({:.0f} m² known){}.".format(
                survey.known_m2, "; {} place{} seen through gaps too narrow for the robot".format(
                    unreachable, "s were" if unreachable != 1 else " was") if unreachable else "")
        return True

    def _go_home(self, exp):
        """Back to the start (or the dock marked while mapping); False when the exploration ended."""
        if not exp.return_home:
            return self._still(exp)
        home, name = self._home_pose()
        with self._lock:
            if not self._still(exp):
                return False
            exp.state, exp.target = RETURNING, (home.x, home.y)
            note = exp.message
            exp.message = "Coming back to {}.".format(name)
            self._changed(exp)
        state, why = "aborted", None
        for _ in range(HOME_TRIES):  # move_base may give up once (a corner, a person); a second try often does
            seq = self._send_home(exp, home, name)
            if seq is None:
                return False
            state, why = self._home_goal_end(exp, seq)
            if state != "aborted":
                break
        if not self._still(exp):
            return False
        with self._lock:
            exp.message = note if state == "succeeded" else "{} It could not get back to {} ({}); the map is " \
                "saved where it stands.".format(note, name, why or state)
        return True

    def _send_home(self, exp, home, name):
        """The goal home's seq; None when the exploration ended (or the goal was refused: failed)."""
        with self._sending:
            if not self._still(exp):
                return None
            try:
                seq = self._robot.run_goto(Goal(home, name if name == DOCK else None))
            except MoveServerError as exc:
                self._fail(exp, "The way back was refused: {}".format(exc))
                return None
            self._seq = seq
            if not self._still(exp):  # a stop came as it was sent: this goal is ours to cancel
                self._robot.cancel_goal(seq)
                return None
        return seq

    def _home_goal_end(self, exp, seq):
        deadline = time.monotonic() + self.return_timeout
        state, why = "active", None
        while self._still(exp) and state in ("active", "canceling") and time.monotonic() < deadline:
            state, why = self._robot.goal_end(seq, POLL)
        return state, why

    def _home_pose(self):
        """(Pose2D, words): the ``dock`` place marked while mapping, else where exploring began."""
        store = self._maps.store
        if store.path == self._maps.marks.path:
            try:
                dock = store.get(DOCK)
                return Pose2D(dock.x, dock.y, dock.yaw), DOCK
            except UnknownWaypoint:
                pass
        return self._home, "where it started"

    def _save(self, exp):
        with self._lock:
            if not self._still(exp):
                return
            exp.state, exp.target = SAVING, None
            note = exp.message
            exp.message = "Saving the map as {}.".format(exp.save_as)
            self._changed(exp)
        try:
            here = self._robot.current_pose()
        except MoveServerError:
            here = None
        try:
            result = self._maps.save(exp.save_as, exp.overwrite, then=exp.then == "navigation", here=here)
            if exp.then == "idle":
                self._modes.switch("idle")
        except MoveServerError as exc:
            self._fail(exp, "The map could not be saved as {}: {}".format(exp.save_as, exc))
            return
        with self._lock:
            exp.map = exp.save_as
            failed = result.get("mode_error")
            after = "now navigating on it" if exp.then == "navigation" else "the robot is idle"
            if failed:
                after = "but navigation on it did not start: {}".format(failed["message"])
            self._end(exp, DONE, "{} Saved as {}, {}.".format(note, exp.save_as, after))

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


class _Goal:
    """A frontier goal under way, and how near the robot has come to it."""

    def __init__(self, seq, target, distance):
        self.seq, self.target = seq, target
        self._best, self._since = distance, time.monotonic()

    def wait(self, robot, timeout):
        robot.goal_end(self.seq, timeout)

    def stalled(self, robot, patience):
        """True once the robot came no ``NEARER`` for ``patience`` s."""
        try:
            here = robot.current_pose()
        except MoveServerError:
            return False
        distance = math.hypot(self.target[0] - here.x, self.target[1] - here.y)
        now = time.monotonic()
        if distance < self._best - NEARER:
            self._best, self._since = distance, now
        return now - self._since > patience


def _still_there(goal, survey):
    """True while a frontier's target lies within KEEP of the goal's: its frontier is not seen yet."""
    return any(_near(f.target, goal.target, KEEP) for f in survey.frontiers)


def _near(a, b, radius):
    return math.hypot(a[0] - b[0], a[1] - b[1]) <= radius

