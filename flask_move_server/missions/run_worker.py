"""The worker's half of the run executor: one waypoint after the other, on a thread of the run's own.

:class:`RunWorker` is what :class:`~flask_move_server.missions.executor.RunExecutor`'s thread
(``run-executor``) runs: send the current stop as a goal through the facade's ``run_goto`` (under
``_sending``, which ``end_by`` takes), wait for that goal's own end by its sequence number, act on
a command (pause, skip, cancel) that came meanwhile, note the stop reached or missed, dwell, and
go on, hold at an order's open end, or finish. It reads and changes the executor's state
(``_run``, ``_command``, ``_seq``) under the executor's lock, as the executor's own methods do.
Pure: no rospy, no Flask.
"""

import logging

from flask_move_server.core.errors import EStopLatched, MoveServerError, UnknownWaypoint
from flask_move_server.core.geometry import Goal, Pose2D
from flask_move_server.missions.run import CANCELED, FAILED, PAUSED, RUNNING, STUCK, SUCCEEDED, WAITING

log = logging.getLogger(__name__)

POLL = 0.25  # s between looks at a command while waiting on a goal (the goal's end wakes it at once)


class RunWorker:
    """The run executor's worker loop (a mixin: the state and the lock are the executor's)."""

    def _drive(self, run):
        """The worker: one waypoint after the other until the run is through, ended or paused for good.

        A bug of ours must not leave a run ``running`` with nothing driving it (every new run refused
        until ``/stop``): it ends the run ``failed``, saying so, and is logged with its traceback."""
        try:
            self._drive_on(run)
        except Exception as exc:
            log.exception("run %d: its worker failed", run.id)
            with self._lock:
                mine = self._run is run
                if mine:
                    self._finish(run, FAILED, "The run stopped on an error of the server's ({}: {}); the log has "
                                              "the details.".format(type(exc).__name__, exc))
            if mine:
                self._robot.halt()  # nothing drives a goal it may have sent: the robot stops

    def _drive_on(self, run):
        while True:
            with self._lock:
                if not self._await_running(run):
                    return
            outcome = self._go(run)
            if outcome is None:  # the run ended meanwhile, or the goal could not be sent
                return
            self._after(run, *outcome)

    def _await_running(self, run):
        """Lock held: wait while paused; False once the run is no longer this worker's."""
        while self._run is run and (run.state in WAITING or run.holding) and not self._closed:
            self._lock.wait()
        return self._run is run and run.state == RUNNING and not self._closed

    def _go(self, run):
        """Send the current waypoint and wait for its end: ``(state, why)``; None when the run is over."""
        try:
            goal = self._goal_of(run)
        except UnknownWaypoint as exc:
            return "missing", str(exc)
        with self._sending:
            with self._lock:
                if self._run is not run or run.state != RUNNING or self._command is not None:
                    return self._command_only()
            try:
                seq = self._robot.run_goto(goal)
            except MoveServerError as exc:
                with self._lock:
                    if self._run is run:
                        self._finish(run, CANCELED if isinstance(exc, EStopLatched) else FAILED,
                                     "The goal to {} was refused: {}".format(run.target, exc))
                return None
            self._seq = seq
        return self._wait_goal(run, seq)

    def _goal_of(self, run):
        """The current stop as a goal: its own pose (an order's node), or its waypoint's (UnknownWaypoint)."""
        pose = run.pose_of(run.index)
        if pose is not None:
            return Goal(pose, run.target)
        waypoint = self._store.get(run.target)
        return Goal(Pose2D(waypoint.x, waypoint.y, waypoint.yaw), waypoint.name)

    def _command_only(self):
        """Lock held: a command came before the goal was sent: act on it as on a canceled goal."""
        return ("canceled", None) if self._command is not None else None

    def _wait_goal(self, run, seq):
        """``(state, why)`` of goal ``seq`` once it ends, or ``canceled`` once a command or another
        command's end of the run came first; a goal of ours still under way then is canceled here
        (it may have been sent just after the stop that ended the run, or the pause, was made)."""
        while True:
            with self._lock:
                interrupted = self._run is not run or self._command is not None
            state, why = self._robot.goal_end(seq, 0 if interrupted else POLL)
            if state not in ("active", "canceling"):  # canceling: its end (and who ended the run) comes next
                return state, why
            if interrupted:
                self._robot.cancel_goal(seq)
                return "canceled", why

    def _after(self, run, state, why):
        """The current waypoint's goal ended in ``state``: act on a command, note it, go on or end."""
        with self._lock:
            if self._run is not run:
                return
            command = self._take_command(run)
            if command == "cancel":
                return
            if state == "succeeded":  # reached, even if a command came as it arrived
                run.visit()
                self._tell(run, "reached", run.trimmed + run.index)
            elif command == "skip":
                run.miss("skipped (POST /runs/{}/skip)".format(run.id))
            elif command == "pause":  # the robot stopped short of it: resume sends it again
                self._pause(run, "Paused at {}: resume sends it again.".format(run.target))
                return
            elif state == "stuck":  # not missed: it could not get on; once it is free, resume goes there
                self._pause(run, "Stuck on the way to {}: {} Then resume the run: it goes there again.".format(
                    run.target, why or "drive it out with the joystick."), STUCK)
                return
            else:
                run.miss(why or "the goal ended {}".format(state))
                if run.on_failure == "stop":
                    self._finish(run, FAILED, "Could not reach {}: {}".format(run.target, why or state))
                    return
            self._changed(run, progress=True)
            self._dwell_then_advance(run, dwell=state == "succeeded" and command is None, pause=command == "pause")

    def _take_command(self, run):
        """Lock held: the pending command, now acted on (a ``cancel`` ends ``run`` here), or None."""
        command, self._command = self._command, None
        if command == "cancel":
            self._canceled(run)
        return command

    def _canceled(self, run):
        """Lock held: ``run`` ends as its own Cancel asked."""
        self._finish(run, CANCELED, "Canceled (POST /runs/{}/cancel).".format(run.id))

    def _pause(self, run, message, state=PAUSED):
        """Lock held: ``run`` waits for a resume (the worker sleeps in :meth:`_await_running`)."""
        why, self._pause_why = self._pause_why, None
        if why and state == PAUSED:
            message, run.charges = "{} {}".format(why, message), run.charges + 1
        run.state, run.message = state, message
        self._changed(run)

    def _dwell_then_advance(self, run, dwell, pause):
        """Lock held: wait ``dwell`` s at a waypoint reached (a command cuts it short), then the next one;
        with ``pause`` (or a pause while waiting), the run then waits there for a resume."""
        if dwell and run.dwell > 0:
            self._lock.wait_for(lambda: self._command is not None or self._run is not run or self._closed,
                                timeout=run.dwell)
            if self._run is not run:
                return
            command = self._take_command(run)
            if command == "cancel":
                return
            pause = command == "pause"
        if not run.advance():
            if run.open_end:
                self._hold(run, pause)
                return
            self._finish(run, SUCCEEDED, summary(run))
        elif pause:
            self._pause(run, "Paused before {}: resume goes there.".format(run.target))
        else:
            self._changed(run, progress=True)

    def _hold(self, run, pause):
        """Lock held: ``run`` reached its last stop, and more may come (:meth:`extend`): it waits there."""
        run.holding = True
        if pause:
            self._pause(run, "Paused at {}: resume waits there for the order's next stops.".format(run.target))
            return
        run.message = "Waiting at {} for the next stops of the order.".format(run.target)
        self._changed(run)


def summary(run):
    """The closing sentence of a run that went through its loops."""
    loops = "{} loops".format(run.loop) if run.loop > 1 else "1 loop"
    charged = {0: "", 1: " It went home to charge on the way, once."}.get(
        run.charges, " It went home to charge on the way, {} times.".format(run.charges))
    if not run.missed:
        return "Visited every waypoint ({}).{}".format(loops, charged)
    return "Done ({}), but {} waypoint visit(s) missed: see 'missed'.{}".format(loops, len(run.missed), charged)
