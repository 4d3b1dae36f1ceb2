"""The one executor of runs: whoever asks (the API, the page, a schedule, MQTT, VDA 5050), it drives.

A run is sent one waypoint at a time as a move_base goal through the Robot facade, and each
result is matched to its own goal by the goal's sequence number: a stale or late result (of a
goal a newer one replaced) never advances a run. Reached: noted as visited, then ``dwell``
seconds, then the next. Not reached: noted as missed with move_base's reason, then the run
ends ``failed`` (``on_failure: stop``) or goes on (``skip``). Pause cancels the goal and keeps
the index; resume sends the current waypoint again; skip notes it as missed and goes on.

Who else commands the robot ends the run (``Robot`` calls :meth:`RunExecutor.end_by`):
``POST /stop``, the e-stop, a ``/goto`` and ``/teleop`` end it ``canceled`` with the reason.
A goal is sent under ``_sending``, which ``end_by`` takes for a ``/goto`` or ``/teleop``, so their
own command is never overtaken by the run's next goal; a stop never waits for it: the worker sees
its run ended (or paused) and cancels a goal it had just sent itself. One thread (``run-executor``)
per active run, its loop :mod:`~flask_move_server.missions.run_worker`; every change is a ``run``
event and is written to the history. Pure: no rospy, no Flask.
"""

import logging
import threading

from flask_move_server.core.errors import (
    MoveServerError,
    RunConflict,
    UnknownRun,
    WrongMode,
)
from flask_move_server.core.geometry import Pose2D
from flask_move_server.missions.history import SAVE_WAIT
from flask_move_server.missions.run import (
    ACTIVE,
    CANCELED,
    INTERRUPTED,
    PAUSED,
    RUNNING,
    SKIPPED,
    SUCCEEDED,
    WAITING,
    Run,
)
from flask_move_server.missions.run_worker import RunWorker, summary

log = logging.getLogger(__name__)

NOT_NAVIGATING = ("Runs need the robot navigating on a map: it is {}. Choose a map to navigate on first "
                  "(POST /mode {{\"mode\": \"navigation\", \"map\": NAME}}; robotctl map use NAME).")


class RunExecutor(RunWorker):
    """Starts, drives and keeps runs; ``robot``: the facade, ``store``: the active map's waypoints."""

    def __init__(self, robot, store, history, events=None, modes=None):
        self._robot = robot
        self._store = store
        self._history = history
        self._events = events
        self._modes = modes
        self._lock = threading.Condition()  # the runs' state
        self._sending = threading.RLock()  # held while a run's goal is sent; end_by waits for it
        self._run = None  # the active run
        self._command = None  # "pause", "skip", "cancel" for the worker to act on
        self._pause_why = None  # said before the pause's message (the battery ran low)
        self._seq = None  # the goal the active run sent last
        self.holds_new_runs = None  # dock/low_battery.py: .why() a new run starts paused (gone home to charge)
        self._worker = None
        self._closed = False
        if modes is not None:
            modes.when_leaving_running(self._leaving_mode)

    # asking ------------------------------------------------------------------

    def start(self, route, trigger="api", poses=None, open_end=False, watch=None, paused=False):
        """Start a run of ``route`` (a checked Route); the run as a dict. Refused with the reason when
        the e-stop is latched, the robot is not navigating, or another run is active.

        A fleet manager's order (VDA 5050) gives ``poses`` (per stop: a Pose2D, or None where the stop
        names a waypoint), ``open_end`` (more stops may come: the run waits at its last one, see
        :meth:`extend`), ``watch(what, value)`` (told ``reached`` with the stop's index counted from the run's
        first stop, and ``ended`` with ``(state, message)``, under the executor's lock: never call back)
        and ``paused`` (it starts paused).
        """
        self._check_waypoints([w for i, w in enumerate(route.waypoints) if poses is None or poses[i] is None])
        mode = self._mode_status()  # before our locks: the mode manager calls us under its own
        held = self.holds_new_runs.why() if self.holds_new_runs is not None and not paused else None
        with self._sending, self._lock:
            self._refuse_start(mode)
            run = Run.of_route(self._history.next_id, route, trigger)
            run.poses, run.open_end, run.watch = (list(poses) if poses is not None else None), open_end, watch
            if paused or held:
                run.state, run.message = PAUSED, held or "Paused before {}: resume goes there.".format(run.target)
            ticket = self._history.add(run)
            self._begin(run)
            started = run.as_dict()
        # Answered once it is on disk (outside the locks: the worker goes on meanwhile): a run acknowledged
        # is one a crash right after cannot lose (a starved writer thread lost one under load).
        if not self._history.saved(ticket):
            log.warning("run %d: not on disk %g s after it started; answered anyway", run.id, SAVE_WAIT)
        if held:
            self.holds_new_runs.held(run.id)  # it goes on by itself once charged
        return started

    def extend(self, run_id, stops, poses, open_end):
        """More stops for run ``run_id`` (a fleet manager released more of its order); a run waiting at its
        last stop goes on. RunConflict when the run is no longer active."""
        self._check_waypoints([w for w, p in zip(stops, poses) if p is None])
        with self._lock:
            run = self._find(run_id)
            if not run.active:
                raise RunConflict("Run {} is {}: it takes no more stops.".format(run_id, run.state))
            run.extend(stops, poses, open_end)
            if run.holding and stops:
                run.holding = False
                run.advance()
            elif run.holding and not open_end:
                run.holding = False
                self._finish(run, SUCCEEDED, summary(run))
                return run.as_dict()
            self._changed(run, progress=True)
            return run.as_dict()

    def scheduled(self, route):
        """A schedule is due: start a run, or keep a ``skipped`` one saying why the robot was busy."""
        busy = self._busy_with()
        if busy is None:
            try:
                return self.start(route, "schedule")
            except MoveServerError as exc:  # what changed since the look above (a waypoint, the e-stop)
                busy = str(exc)
        with self._lock:
            run = Run.of_route(self._history.next_id, route, "schedule")
            run.end(SKIPPED, "Not run at its scheduled time: {}".format(busy))
            self._history.add(run)
            self._changed(run)
        log.info("run %d of %s skipped: %s", run.id, route.name, busy)
        return run.as_dict()

    def _busy_with(self):
        """What keeps a timetable from starting a run now, said as what happened (not what to do), or None."""
        with self._lock:
            other = self._run if self._run is not None and self._run.active else None
            if other is not None:
                return "the robot was doing another round ({}).".format(other.route or "a list of places")
        if self._robot.estop_status()["latched"]:
            return "the e-stop was on."
        mode = self._mode_status()
        if mode is not None and (mode["mode"] != "navigation" or mode["state"] != "running"):
            return "the robot was not navigating on a map ({}).".format(
                mode["mode"] if mode["state"] == "running" else "{} {}".format(mode["mode"], mode["state"]))
        busy = self._robot.busy_with()
        return busy[0].lower() + busy[1:] if busy else None

    def pause(self, run_id, why=None):
        """Pause the run: its goal stops; ``why``, if given, is said before its "paused at ..." message."""
        with self._lock:
            self._pause_why = why
        try:
            return self._act(run_id, "pause", (RUNNING,), "paused")
        except RunConflict:
            with self._lock:
                self._pause_why = None
            raise

    def skip(self, run_id):
        with self._lock:
            if self._find(run_id).trigger == "vda5050":
                raise RunConflict("Run {} is a fleet manager's order (VDA 5050): its nodes are not skipped here. "
                                  "Cancel the run, or let the fleet manager change the order.".format(run_id))
        return self._act(run_id, "skip", ACTIVE, "skipped")

    def cancel(self, run_id):
        return self._act(run_id, "cancel", ACTIVE + (INTERRUPTED,), "canceled")

    def resume(self, run_id, why=None):
        """Go on: a paused run sends its current waypoint again; an interrupted one starts a worker anew.
        ``why``, if given, is the run's message meanwhile (it went on by itself, after charging)."""
        mode = self._mode_status()
        with self._sending, self._lock:
            run = self._find(run_id)
            if run.state == INTERRUPTED and run.trigger == "vda5050":
                raise RunConflict("Run {} was a fleet manager's order (VDA 5050): after a restart the fleet manager "
                                  "sends it again; it is not resumed here.".format(run_id))
            if run.state in WAITING:
                self._robot.refuse_motion("runs are")
                run.state, run.message, self._command = RUNNING, why, None
                self._changed(run)
                return run.as_dict()
            if run.state != INTERRUPTED:
                raise RunConflict("Run {} is {}: only a paused, stuck or interrupted run can be resumed.".format(
                    run_id, run.state))
            self._refuse_start(mode)
            run.state, run.message = RUNNING, None
            self._begin(run)
            return run.as_dict()

    def end_by(self, reason, wait_for_send=True):
        """Someone else commands the robot (``reason`` says who): the active run ends ``canceled``.

        ``wait_for_send``: first wait for a goal of the run being sent, so that a command sending
        its own goal comes after it (a ``/goto``); a stop does not wait: the worker cancels a goal it
        sent once it sees its run ended. True when a run was ended.
        """
        if not wait_for_send:
            return self._end_active(reason)
        with self._sending:  # two plain locks: an ExitStack was a dozen calls before every /goto's publish
            return self._end_active(reason)

    def _end_active(self, reason):
        with self._lock:
            run = self._run
            if run is None or not run.active:
                return False
            self._finish(run, CANCELED, reason)
            return True

    def interrupt(self, why):
        """The server is stopping: the active run is ``interrupted`` (resumable after the restart)."""
        with self._lock:
            run = self._run
            if run is not None and run.active:
                run.state, run.message = INTERRUPTED, why
                self._changed(run)
                self._run = None
                self._lock.notify_all()

    # reading -----------------------------------------------------------------

    def runs(self):
        """The kept runs, newest first, as dicts."""
        with self._lock:
            return [self._shown(r) for r in self._history.all()]

    def get(self, run_id):
        with self._lock:
            return self._shown(self._find(run_id))

    def active(self):
        """The active run as a dict, or None."""
        with self._lock:
            return self._shown(self._run) if self._run is not None else None

    def _shown(self, run):
        distance = None
        if run is self._run and run.state == RUNNING:
            nav = self._robot.navigation_status()
            if nav.get("goal_id") == self._seq:
                distance = nav.get("distance_remaining")
        return run.as_dict(distance)

    # the rules ---------------------------------------------------------------

    def _check_waypoints(self, names):
        """Every waypoint of a route exists on the active map (UnknownWaypoint, 404, with close names) and
        lies outside its enabled zones (InZone, 409, naming the stop and the zone), before the robot moves."""
        zones = getattr(self._robot, "zones", None)
        for name in dict.fromkeys(names):
            waypoint = self._store.get(name)
            if zones is not None:
                zones.check(Pose2D(waypoint.x, waypoint.y, waypoint.yaw), waypoint.name)

    def _mode_status(self):
        """``GET /mode``'s body when this server runs the stack, else None (the stack is someone else's)."""
        return self._modes.status() if self._modes is not None and self._modes.runs_stack else None

    def _leaving_mode(self, status):
        """The mode manager leaves a running stack (under its lock): the run under way ends with the reason."""
        with self._lock:
            run = self._run
            if run is not None and run.active:
                self._finish(run, CANCELED, "The robot switched to {}, which ended the run.".format(status["mode"]))

    def _refuse_start(self, status):
        """Lock held: why no run can start now (raised), or nothing; ``status``: the mode's, or None."""
        if self._closed:
            raise RunConflict("The server is shutting down: no run starts now.")
        self._robot.refuse_motion("runs are")
        if self._run is not None and self._run.active:
            raise RunConflict("Run {} ({}) is {}: cancel it first (POST /runs/{}/cancel), or wait until it "
                              "ends.".format(self._run.id, self._run.route or "unnamed", self._run.state,
                                             self._run.id))
        if status is not None and (status["mode"] != "navigation" or status["state"] != "running"):
            doing = status["mode"] if status["state"] == "running" else "{} ({})".format(
                status["mode"], status["state"])
            raise WrongMode(NOT_NAVIGATING.format(doing))

    def _find(self, run_id):
        run = self._history.get(run_id)
        if run is None:
            raise UnknownRun("No run {} is kept (the newest 50 are; GET /runs lists them).".format(run_id))
        return run

    def _act(self, run_id, command, states, done):
        """Pause, skip or cancel: allowed in ``states``; the goal under way is stopped at once."""
        with self._lock:
            run = self._find(run_id)
            if run.state not in states:
                raise RunConflict("Run {} is {}: it cannot be {} now.".format(run_id, run.state, done))
            if run.state != RUNNING or run.holding:  # paused, interrupted, waiting: no goal under way
                self._act_at_rest(run, command)
                return self._shown(run)
            self._command = command
            self._lock.notify_all()
        self._robot.halt()  # outside the lock: the worker may be waiting to send under it
        return self._settled(run)

    def _act_at_rest(self, run, command):
        """Lock held: skip or cancel a run that is not driving (paused, interrupted)."""
        if command == "cancel":
            self._canceled(run)
            return
        if command == "pause":  # waiting at the last stop of an order for more of it
            self._pause(run, "Paused at {}: resume waits there for the order's next stops.".format(run.target))
            return
        if run.holding:
            raise RunConflict("Run {} waits at its last stop for more of its order: nothing to skip.".format(run.id))
        run.miss("skipped (POST /runs/{}/skip)".format(run.id))
        if not run.advance():
            self._finish(run, SUCCEEDED, summary(run))
            return
        run.state = PAUSED if run.state in WAITING else run.state  # a stuck run skipped on: paused before the next
        run.message = "Paused before {}: resume goes there.".format(run.target)
        self._changed(run)

    def _settled(self, run):
        """The run once the worker has acted on its command (briefly waited for), as a dict."""
        with self._lock:
            self._lock.wait_for(lambda: self._command is None or self._run is not run, timeout=2.0)
            return self._shown(run)

    def _begin(self, run):
        """Lock held: ``run`` becomes the active run, driven by a worker thread of its own."""
        self._run, self._command, self._seq = run, None, None
        self._changed(run)
        log.info("run %d (%s, %s): started, %d waypoints, %s loop(s)", run.id, run.route or "unnamed", run.trigger,
                 len(run.waypoints), run.loops or "endless")
        self._worker = threading.Thread(target=self._drive, args=(run,), name="run-executor", daemon=True)
        self._worker.start()

    def _finish(self, run, state, message):
        """Lock held: ``run`` ends in ``state`` saying ``message``."""
        run.end(state, message)
        run.holding = False
        if self._run is run:
            self._run, self._command = None, None
        self._changed(run)
        self._tell(run, "ended", (state, message))
        log.info("run %d: %s%s", run.id, state, " ({})".format(message) if message else "")

    def _tell(self, run, what, value):
        """Lock held: the run's watcher (a fleet manager's order) hears ``what`` happened."""
        if run.watch is not None:
            try:
                run.watch(what, value)
            except Exception:  # a watcher's bug must not stop the robot's run
                log.exception("run %d: its watcher failed on %s", run.id, what)

    def _changed(self, run, progress=False):
        """Lock held: write the runs soon (``progress``: only where it is, written less often), tell
        ``GET /events``, and wake whoever waits on the run."""
        self._lock.notify_all()
        self._history.changed(progress)
        if self._events is not None:
            self._events.publish("run", self._shown(run))

    def close(self):
        """The server stops: the active run is left ``interrupted``; the worker ends. Idempotent."""
        self.interrupt("The server stopped while this run was under way; resume it to go on.")
        with self._lock:
            self._closed = True
            self._lock.notify_all()
        worker = self._worker
        if worker is not None and worker is not threading.current_thread():
            worker.join(2.0)
        self._history.close()

