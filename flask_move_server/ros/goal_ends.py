"""How a goal to move_base ends: its states, and the ends of the :class:`~flask_move_server.ros.navigator.Navigator`.

A goal ends once: move_base's word (``_done``), a newer goal replacing it, or the server giving it
up (``abandon``: the master is gone, the stack switched, no acknowledgement within
``ack_patience``). Each end is told once to every :meth:`Navigator.when_ended` listener, with the
navigator's lock released. :class:`GoalEnds` is the navigator's half that does this; it uses the
navigator's lock and fields (``_cond``, ``_seq``, ``_state``, ``_goal``, ...).
"""

import logging
import time

from actionlib_msgs.msg import GoalStatus

from flask_move_server.core.goal_endings import failure_sentence, replaced_sentence, said_sentence

log = logging.getLogger("flask_move_server.ros.navigator")  # the goal lines' logger, as before the split

IDLE, ACTIVE, CANCELING, SUCCEEDED, ABORTED, CANCELED, REJECTED = (
    "idle", "active", "canceling", "succeeded", "aborted", "canceled", "rejected",
)
# A goal held while the robot gets itself out (recovery/recovery.py): move_base has let go of it, the
# server has not. ``/status`` says ``stuck``; a waiting client still waits (it is under way: ``active``).
# ``stuck``: it ended so, the robot could not get itself out.
RECOVERING, STUCK = "recovering", "stuck"
TERMINAL = (SUCCEEDED, ABORTED, CANCELED, REJECTED, STUCK)
UNDER_WAY = (ACTIVE, CANCELING)  # move_base has the goal: its word ends it
HELD = UNDER_WAY + (RECOVERING,)  # a cancel, a newer goal or a give-up ends it
ENDS_KEPT = 16  # replaced goals whose ends are kept for a client still waiting on one

_FROM_STATUS = {
    GoalStatus.SUCCEEDED: SUCCEEDED,
    GoalStatus.ABORTED: ABORTED,
    GoalStatus.REJECTED: REJECTED,
    GoalStatus.PREEMPTED: CANCELED,
    GoalStatus.RECALLED: CANCELED,
}


class GoalEnds:
    """The :class:`~flask_move_server.ros.navigator.Navigator`'s goal ends (a mixin of it)."""

    def _keep_end(self):
        """Lock held, a newer goal about to replace this one: keep how it ended for its waiting client.

        Only the facts (on the way to the publish); goal_endings.replaced_end makes the answer if someone asks.
        """
        if self._seq:
            self._ends[self._seq] = (self._state, self._message, self._goal.target if self._goal else None)
            if len(self._ends) > ENDS_KEPT:
                self._ends.popitem(last=False)

    def _replaced_facts(self):
        """Lock held, a newer goal about to replace this one: ``(seq, state, goal, message)`` when it was
        under way, else None (its end was told when it came). Only the facts, on the way to the
        publish: :func:`end_of_replaced` makes the end told once the new goal is on its way."""
        if not self._seq or self._state not in HELD:
            return None
        return self._seq, ACTIVE if self._state == RECOVERING else self._state, self._goal, self._message

    def _end_of_current(self):
        """Lock held, the current goal just ended: ``(seq, state, target, pose, why)`` for :meth:`when_ended`."""
        goal = self._goal
        return (self._seq, self._state, goal.target if goal else None, goal.pose if goal else None,
                self._why(self._state))

    def _tell_end(self, end):
        """Tell ``end`` (or nothing, for None) to every :meth:`when_ended` listener; no lock held."""
        if end is None:
            return
        for callback in list(self._end_listeners):
            try:
                callback(*end)
            except Exception:  # a listener's bug must not lose the goal's end for the others, nor break actionlib
                log.exception("goal %d: a listener of its end failed", end[0])

    def _done(self, seq, status):
        self._acknowledged(seq)
        state = self._lost_end(seq) if status == GoalStatus.LOST else _FROM_STATUS.get(status, ABORTED)
        said = self._said(state)
        if state == ABORTED and self._held_by_judge(seq, said):
            return
        self._finish(seq, state, said)
        self._goal_lines.info("goal %d: %s%s", seq, state, " ({})".format(said) if said else "")

    def _held_by_judge(self, seq, said):
        """True when the judge of aborts (``judge_aborts``) held goal ``seq`` instead of letting it end."""
        judge = self._judge
        if judge is None:
            return False
        try:
            return bool(judge(seq, said))
        except Exception:  # a judge's bug must not lose the goal's end
            log.exception("goal %d: judging its abort failed", seq)
            return False

    def _lost_end(self, seq):
        """A goal actionlib's client calls lost: ``canceled`` when we were canceling it, else ``aborted``.

        actionlib calls a goal canceled before move_base acknowledged it lost at move_base's next
        status without it (a Stop just after a goal, move_base busy). move_base keeps the cancel
        and recalls the goal when it comes (C++ and Python actionlib alike), so it was canceled.
        """
        with self._cond:
            return CANCELED if seq == self._seq and self._state == CANCELING else ABORTED

    def _said(self, state):
        """move_base's own reason for a goal that failed (its status text: "Failed to find a valid plan…"), or None.

        Called in the goal's done callback, while the client still holds that goal.
        """
        if state not in (ABORTED, REJECTED) or self._client is None:
            return None
        try:
            text = self._client.get_goal_status_text()
        except Exception:  # a reason is a nicety: never let it lose the goal's end
            return None
        return text.strip() or None

    def _finish(self, seq, state, said=None):
        ended = None
        with self._cond:
            if seq == self._seq and self._state in UNDER_WAY:  # the first end of a goal is its end
                self._state = state
                if said:
                    self._message = said_sentence(state, self._goal.target if self._goal else None, said)
                ended = self._end_of_current()
                self._cond.notify_all()
                if self.trips is not None:
                    self.trips.ended()
        self._tell_end(ended)

    def _master_lost(self):
        """No master: move_base's word may never come, so a goal under way ends ``aborted`` now."""
        self.abandon("The ROS master stopped answering, so the goal was given up (and a cancel sent to "
                     "move_base); send it again once /health says \"ros\": \"connected\".",
                     "the ROS master stopped answering")

    def abandon(self, why, reason, seq=None):
        """Give up the goal under way (goal ``seq`` only, when given): ``aborted`` with the sentence
        ``why``, its cancel sent; True when one was. For a goal whose move_base may never answer
        again: the master is gone, the stack is being switched or stopped, no acknowledgement."""
        with self._cond:
            if self._state not in HELD or (seq is not None and seq != self._seq):
                return False
            seq, self._state, self._message = self._seq, ABORTED, why
            ended = self._end_of_current()
            self._cond.notify_all()
            if self.trips is not None:
                self.trips.ended()
        log.error("goal %d: aborted, %s", seq, reason)
        try:
            self._send_cancel()  # over the open connection: move_base must not resume it later
        except Exception as exc:
            log.warning("goal %d: could not send its cancel: %s", seq, exc)
        self._tell_end(ended)
        return True

    def _acknowledged(self, seq):
        with self._cond:
            if seq == self._seq:
                self._unacknowledged = None

    def _watch_acknowledgements(self):
        """Abort a goal move_base has not acknowledged within ``ack_patience`` (action mode).

        move_base answers a goal at once (active, or rejected); one sent as its stack was going away
        had no answer ever and stayed ``active`` for good: a waiting client waited its whole timeout.
        The watch sleeps until the pending goal is due (or ``ack_patience`` when none is: a goal
        sent meanwhile is due later), never on the goals' condition: a ``/goto`` that woke it
        handed it the GIL just before its publish (~0.03 ms of every goal).
        """
        while not self._closed:
            with self._cond:
                pending = self._unacknowledged
            left = self.ack_patience if pending is None else pending[1] + self.ack_patience - time.monotonic()
            if left > 0:
                self._closing.wait(left)
                continue
            with self._cond:
                if self._unacknowledged is not pending:
                    continue  # acknowledged, or a newer goal, meanwhile
                self._unacknowledged = None
            seq = pending[0]
            self.abandon("move_base did not acknowledge the goal within {:.0f} s, so it was given up: is the "
                         "navigation stack running? (GET /mode, GET /health)".format(self.ack_patience),
                         "move_base did not acknowledge it within {:.0f} s".format(self.ack_patience), seq)


def end_of_replaced(facts):
    """The end ``(seq, state, target, pose, why)`` for :meth:`Navigator.when_ended` of a goal replaced
    while under way (``facts`` from :meth:`Navigator._replaced_facts`, or None): ``canceled``,
    "replaced by a newer goal", or the cancel's sentence when one was sent."""
    if facts is None:
        return None
    seq, state, goal, message = facts
    target = goal.target if goal else None
    if state == ACTIVE:
        why = replaced_sentence(target)
    else:
        why = message or failure_sentence(CANCELED, target)
    return seq, CANCELED, target, goal.pose if goal else None, why
