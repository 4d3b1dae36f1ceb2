"""A goal held while the robot gets itself out: the :class:`~flask_move_server.ros.navigator.Navigator`'s half.

A robot that is stuck (``recovery/``) has its goal *held*: move_base lets go of it, the server
does not. ``/status`` says ``stuck``; a client waiting for the goal goes on waiting, and after the
robot backed out the same goal (same sequence number) is sent again, or it ends ``stuck``. A goal
move_base aborts may be held instead of ended: the judge (``judge_aborts``) decides, before the end
is told. :class:`GoalHold` uses the navigator's lock and fields (``_cond``, ``_sending``, ``_seq``,
``_state``, ``_goal``, ...), as :class:`~flask_move_server.ros.goal_ends.GoalEnds` does.
"""

from flask_move_server.core.goal_endings import said_sentence
from flask_move_server.ros.goal_ends import ACTIVE, RECOVERING, STUCK


class GoalHold:
    """The navigator's held goals (a mixin of it)."""

    def judge_aborts(self, judge):
        """Ask ``judge(seq, said)`` of each goal move_base aborts, before its end is told: a judge that
        holds it (:meth:`hold`: the robot is stuck, not the goal unreachable) returns True, and the goal is
        not ended. Called in actionlib's thread, outside the navigator's locks."""
        self._judge = judge

    def hold(self, seq, why, cancel=True):
        """Hold goal ``seq`` under way while the robot gets itself out: move_base lets go of it (a cancel
        is sent unless ``cancel`` is False: it has just aborted it), ``/status`` says ``stuck`` with ``why``,
        and whoever waits for it goes on waiting. True when held.

        Without a cancel (the judge of aborts, in actionlib's thread under its list lock) the sending
        lock is not taken: a ``goto`` holds it while it waits for that list lock.
        """
        if not cancel:
            return self._hold(seq, why)
        with self._sending:  # as cancel(): a goal racing the hold is not the one canceled
            held = self._hold(seq, why)
            if held:
                self._send_cancel()
        return held

    def _hold(self, seq, why):
        with self._cond:
            if seq != self._seq or self._state not in (ACTIVE, RECOVERING):
                return False
            self._state, self._message, self._unacknowledged = RECOVERING, why, None
            self._cond.notify_all()
        self._goal_lines.info("goal %d: held, the robot is stuck (%s)", seq, why)
        return True

    def under_way(self):
        """The sequence number of the goal move_base has now (``active``), or None."""
        with self._cond:
            return self._seq if self._state == ACTIVE else None

    def holding(self, seq):
        """True while goal ``seq`` is held (nobody ended nor replaced it meanwhile)."""
        with self._cond:
            return seq == self._seq and self._state == RECOVERING

    def say(self, seq, why):
        """What ``/status`` says of held goal ``seq`` from now on."""
        with self._cond:
            if seq == self._seq and self._state == RECOVERING:
                self._message = why

    def retry(self, seq):
        """Send held goal ``seq`` to move_base again (the robot got itself out): under way as before, the
        same sequence number. True when sent."""
        with self._sending:
            with self._cond:
                if seq != self._seq or self._state != RECOVERING:
                    return False
                goal = self._goal
                self._state, self._message, self._feedback_pose = ACTIVE, None, None
                if self._client is not None:
                    self._expect_acknowledgement(seq)
                self._cond.notify_all()
            self._publish_goal(seq, goal)
        self._goal_lines.info("goal %d: sent again after backing out", seq)
        self._build_ahead()
        return True

    def end_stuck(self, seq, why):
        """Held goal ``seq`` ends ``stuck`` with ``why``: the robot could not get itself out. True when it did."""
        return self.end_held(seq, STUCK, why)

    def end_held(self, seq, state, why=None):
        """Held goal ``seq`` ends in ``state``: ``stuck`` saying ``why``, or ``aborted`` as move_base said
        (``why``: its words; the robot was not stuck after all). True when it did."""
        with self._cond:
            if seq != self._seq or self._state != RECOVERING:
                return False
            self._state = state
            self._message = why if state == STUCK else (said_sentence(state, self._target(), why) if why else None)
            ended = self._end_of_current()
            self._cond.notify_all()
            if self.trips is not None:
                self.trips.ended()
        self._goal_lines.info("goal %d: %s", seq, state)
        self._tell_end(ended)
        return True

    def _target(self):
        return self._goal.target if self._goal else None
