"""The explorer's worker: mapping, frontiers, home, save, on the ``explorer`` thread.

:class:`ExplorerWorker` is what :class:`~flask_move_server.explore.explorer.Explorer`'s thread runs,
steps 1-4 of its docstring: switch to mapping, survey the frontiers and follow the best (kept
while its frontier is there, blacklisted when aborted, stalled or reached), go home (or to the
``dock`` marked while mapping), save and navigate or idle. It reads and changes the explorer's
state under the explorer's lock, as the explorer's own methods do. Pure: no rospy, no Flask.
"""

import dataclasses
import logging
import math
import time

from flask_move_server.core.errors import MoveServerError, NoPose
from flask_move_server.core.geometry import Goal, Pose2D
from flask_move_server.explore.exploration import DONE, EXPLORING, FAILED, RETURNING, SAVING, STUCK
from flask_move_server.explore.stuck import STUCK_AFTER, Trail, moved, stuck_message
from flask_move_server.waypoints import make_waypoint
from flask_move_server.waypoints.yaml_format import DOCK
from flask_move_server.zones import blocking, distance

log = logging.getLogger(__name__)

POLL = 0.5  # s between looks at the map and the goal (a goal's end wakes the worker at once)
NEARER = 0.1  # m the robot must come nearer its target within progress_timeout
KEEP = 0.75  # m: a goal is kept while a frontier's target lies this near it
HOME_TRIES = 2  # goals home before the map is saved where the robot stands
GROWTH_M2 = 0.25  # m² the known map must grow by ...
GROWTH_PATIENCE = 2  # ... within this many progress_timeouts, or the goal under way is given up


class ExplorerWorker:
    """The worker's half of Explorer (a mixin: the state and the lock are Explorer's)."""

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
        empty, unmoved, trail = 0, 0, Trail(self._home)
        lost, growth = None, Growth(self.progress_timeout * GROWTH_PATIENCE)
        while self._still(exp):
            if goal is not None:
                ended, goal = goal, self._follow(goal, blacklist)
                if goal is None:
                    growth.stop()  # a goal ended by itself: no chain of replaced goals to judge
                if ended.stuck:  # the robot said so itself, and could not get out: no frontier is to blame
                    return self._stuck(exp, 0, ended.stuck)
                if goal is None:
                    unmoved = self._unmoved_after(ended, unmoved, trail)
                    if unmoved >= STUCK_AFTER:
                        if not self._can_move(exp, trail):
                            return self._stuck(exp, unmoved)
                        unmoved = 0  # it moved: those frontiers were out of reach
            survey = self._survey(exp, blacklist)
            lost = None if survey is not None else lost or time.monotonic()
            if lost is not None and time.monotonic() - lost > self.progress_timeout:
                return self._fail(exp, "The robot's place on the map was not known for {:g} s: is mapping running? "
                                  "(GET /health says what is missing.) The map made so far stays, unsaved.".format(
                                      self.progress_timeout))
            if goal is not None and survey is not None and growth.stalled(survey.known_m2):  # a chain replaced
                log.info("explorer: nothing new mapped for %g s while going to (%.2f, %.2f): given up",
                         growth.patience, *goal.target)
                blacklist.append(goal.target)
                self._robot.cancel_goal(goal.seq)
                goal = None  # the frontiers it danced between are left; the next survey picks another
            if goal is not None and survey is not None and not _still_there(goal, survey):
                goal = None  # its frontier was seen: the next goal replaces this one (no cancel, no blacklist)
                growth.watch(survey.known_m2)
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
        """The frontiers on the latest map from where the robot stands (None: no pose or map now), the
        zones drawn while mapping as walls."""
        from flask_move_server.explore import frontiers  # numpy: loaded by the first exploration, not at rest

        try:
            _, grid = self._maps.source.current()
            pose = self._robot.current_pose()
        except (MoveServerError, NoPose) as exc:
            log.info("explorer: no map or pose now (%s)", exc)
            time.sleep(POLL)
            return None
        zones = self._maps.store.zones()
        inside = [z.name for z in zones if z.kind == "keepout" and distance(z, pose.x, pose.y) == 0]
        grid = frontiers.walled(grid, zones, skip=inside)  # a no-go area the robot is in: it may drive out
        survey = _outside(frontiers.survey(grid, (pose.x, pose.y), self.radius, blacklist=blacklist), zones,
                          self.radius)
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
        if state == "stuck":  # recovery/: stuck and not backed out; the frontier is not given up
            goal.stuck = why or "stuck"
            return None
        if state not in ("active", "canceling"):
            if state != "preempted":
                log.info("explorer: frontier at (%.2f, %.2f) given up: %s %s", *goal.target, state, why or "")
                blacklist.append(goal.target)
                goal.given_up = True
            return None
        if goal.stalled(self._robot, self.progress_timeout):
            log.info("explorer: no progress toward (%.2f, %.2f) for %g s", *goal.target, self.progress_timeout)
            blacklist.append(goal.target)
            goal.given_up = True
            self._robot.cancel_goal(goal.seq)
            return None
        return goal

    def _unmoved_after(self, goal, unmoved, trail):
        """Frontier goals given up in a row without the robot moving, counting ``goal`` (just ended)."""
        try:
            here = self._robot.current_pose()
        except NoPose:
            return unmoved
        trail.add(here)
        return unmoved + 1 if goal.given_up and not moved(goal.start, here) else 0

    def _can_move(self, exp, trail):
        """After frontiers given up without moving: True when a goal back to a place the robot has been
        moves it (or there is no such place to tell by); False when it gets nowhere either."""
        try:
            here = self._robot.current_pose()
        except NoPose:
            return True  # cannot tell now: exploring goes on as before
        back = trail.back_to(here)
        if back is None:
            return True
        with self._lock:
            exp.message = "Checking the robot can still move: back to x {:.1f}, y {:.1f}.".format(back.x, back.y)
            self._changed(exp)
        goal = self._send(exp, (back.x, back.y), counted=False)
        if goal is None:
            return True  # ended meanwhile (or refused: failed); the caller sees it
        deadline = time.monotonic() + self.progress_timeout
        state = "active"
        while self._still(exp) and state in ("active", "canceling") and time.monotonic() < deadline:
            state, _ = self._robot.goal_end(goal.seq, POLL)
        self._robot.cancel_goal(goal.seq)
        try:
            return state == "succeeded" or moved(here, self._robot.current_pose())
        except NoPose:
            return True

    def _stuck(self, exp, given_up, said=None):
        """The robot cannot move: the exploration ends ``stuck``, nothing saved, mapping goes on. ``said``:
        what the robot said of it (recovery/), else it was told by ``given_up`` frontiers in a row."""
        self._cancel_own_goal()
        here = self._robot.current_pose()
        with self._lock:
            if self._still(exp):
                self._end(exp, STUCK, stuck_message(here, given_up, exp.frontiers + given_up, said))
        return False

    def _send(self, exp, target, counted=True):
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
                exp.goals += 1 if counted else 0
                exp.target = target
                self._seq = seq
                self._changed(exp)
        return _Goal(seq, target, here)

    def _explored(self, exp, survey):
        unreached = self._unreached(len(survey.unreachable))  # reads the zones: not under our lock
        with self._lock:
            if not self._still(exp):
                return False
            exp.message = "The whole reachable flat is mapped ({:.0f} m² known){}.".format(survey.known_m2, unreached)
        return True

    def _unreached(self, unreachable):
        """What is said of the frontiers no reachable cell serves: through narrow gaps, or beyond zones."""
        if not unreachable:
            return ""
        where = "through gaps too narrow for the robot"
        if any(zone.enabled for zone in self._maps.store.zones()):
            where += " or beyond its zones"
        return "; {} place{} seen {}".format(unreachable, "s were" if unreachable != 1 else " was", where)

    def _go_home(self, exp):
        """Back to the start (or the dock marked while mapping); False when the exploration ended."""
        if not exp.return_home:
            return self._still(exp)
        home, name, dock = self._home_pose()
        with self._lock:
            if not self._still(exp):
                return False
            exp.state, exp.target = RETURNING, (home.x, home.y)
            note = exp.message
            exp.message = "Coming back to {}.".format(name)
            self._changed(exp)
        state, why = "aborted", None
        for _ in range(HOME_TRIES):  # move_base may give up once (a corner, a person); a second try often does
            seq = self._send_home(exp, home, dock)
            if seq is None:
                return False
            state, why = self._home_goal_end(exp, _Goal(seq, (home.x, home.y), self._pose_or(home)))
            if state not in ("aborted", "stalled"):
                break
        if not self._still(exp):
            return False
        with self._lock:
            exp.message = note if state == "succeeded" else "{} It could not get back to {} ({}); the map is " \
                "saved where it stands.".format(note, name, why or state)
        return True

    def _send_home(self, exp, home, dock):
        """The goal home's seq (named ``dock``, the dock's name, if it goes there); None when the exploration
        ended (or the goal was refused: failed)."""
        with self._sending:
            if not self._still(exp):
                return None
            try:
                seq = self._robot.run_goto(Goal(home, dock))
            except MoveServerError as exc:
                self._fail(exp, "The way back was refused: {}".format(exc))
                return None
            self._seq = seq
            if not self._still(exp):  # a stop came as it was sent: this goal is ours to cancel
                self._robot.cancel_goal(seq)
                return None
        return seq

    def _pose_or(self, fallback):
        """Where the robot stands, or ``fallback`` when that is not known now."""
        try:
            return self._robot.current_pose()
        except MoveServerError:
            return fallback

    def _home_goal_end(self, exp, goal):
        """How the goal home ended: move_base's (state, why), or ``stalled`` (canceled here) when it brought
        the robot no nearer for ``progress_timeout`` s or took longer than ``return_timeout`` s."""
        deadline = time.monotonic() + self.return_timeout
        state, why = "active", None
        while self._still(exp) and state in ("active", "canceling"):
            if goal.stalled(self._robot, self.progress_timeout) or time.monotonic() > deadline:
                log.info("explorer: no progress home for %g s", self.progress_timeout)
                self._robot.cancel_goal(goal.seq)
                return "stalled", "it came no nearer for {:g} s".format(self.progress_timeout)
            state, why = self._robot.goal_end(goal.seq, POLL)
        return state, why

    def _home_pose(self):
        """(Pose2D, words, dock's name or None): the dock marked while mapping, else where exploring began."""
        store = self._maps.store
        dock = store.dock() if store.path == self._maps.marks.path else None
        if dock is not None:
            return Pose2D(dock.x, dock.y, dock.yaw), dock.name, dock.name
        return self._home, "where it started", None

    def _mark_the_dock(self):
        """A map made without a dock marked gets one where exploring began (the robot left its charger):
        ``dock``, which the owner may rename in their words (the role stays)."""
        store = self._maps.store
        if store.path != self._maps.marks.path or store.dock() is not None:
            return
        if any(waypoint.name == DOCK for waypoint in store.all()):
            return  # the owner's own place of that name, whose dock role was taken: left as it is
        home = self._home
        try:
            store.put(make_waypoint(DOCK, home.x, home.y, home.yaw), dock=True)
        except MoveServerError as exc:  # a place named dock that is no dock, a full file: saved without one
            log.warning("the map is saved without a dock: %s", exc)

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
        self._mark_the_dock()
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


class Growth:
    """Whether the map grows while goals replace each other: each frontier seen before it is reached,
    the next sent, and so on. Where two frontiers take turns and nothing new is mapped, that would go
    on for ever (each goal is new, so none is "no nearer" for long); ``stalled`` says when to give the
    goal under way up. A goal that ends by itself ends the chain (:meth:`stop`)."""

    def __init__(self, patience):
        self.patience = patience
        self._most = self._since = None  # None: no chain watched

    def watch(self, known_m2):
        """A goal was replaced: the chain's watch starts, unless one runs."""
        if self._since is None:
            self._most, self._since = known_m2, time.monotonic()

    def stop(self):
        self._most = self._since = None

    def stalled(self, known_m2):
        """True once the chain mapped less than GROWTH_M2 more for ``patience`` s (its watch then ends)."""
        if self._since is None:
            return False
        now = time.monotonic()
        if known_m2 >= self._most + GROWTH_M2:
            self._most, self._since = known_m2, now
            return False
        if now - self._since > self.patience:
            self.stop()
            return True
        return False


class _Goal:
    """A frontier goal under way, and how near the robot has come to it."""

    def __init__(self, seq, target, start):
        self.seq, self.target, self.start = seq, target, start  # start: where the robot stood as it was sent
        self.given_up = False  # aborted or stalled: its frontier blacklisted
        self.stuck = None  # ended stuck (the robot said so, recovery/): what it said
        self._best, self._since = math.hypot(target[0] - start.x, target[1] - start.y), time.monotonic()

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


def _outside(survey, zones, radius):
    """``survey`` without the frontiers whose target lies in or beside an enabled zone (one the robot is
    in is left out of the walls, so it can drive out: a goal into it would be refused, ``in_zone``)."""
    kept, dropped = [], []
    for frontier in survey.frontiers:
        (dropped if blocking(zones, frontier.target[0], frontier.target[1], radius) else kept).append(frontier)
    if not dropped:
        return survey
    return dataclasses.replace(survey, frontiers=tuple(kept), unreachable=survey.unreachable + tuple(dropped))


def _still_there(goal, survey):
    """True while a frontier's target lies within KEEP of the goal's: its frontier is not seen yet."""
    return any(_near(f.target, goal.target, KEEP) for f in survey.frontiers)


def _near(a, b, radius):
    return math.hypot(a[0] - b[0], a[1] - b[1]) <= radius
