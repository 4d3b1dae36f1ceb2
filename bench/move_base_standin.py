"""A move_base for the goal benchmark, in a process of its own: actionlib servers that note arrivals.

Each ``--action`` namespace gets a real ``actionlib.ActionServer`` for ``MoveBaseAction`` that
behaves the way move_base does towards a client: a new goal is accepted and preempts the one
under way, feedback comes at 10 Hz while a goal drives, a goal not replaced succeeds after
``--drive`` s, and the status array goes out at actionlib's 5 Hz and on every change. Every goal's
arrival is printed on stdout as ``goal <action> <x> <time.monotonic()>`` (one clock for every
process on Linux), so the bench can time it from the moment its HTTP client sent the request.

``--succeed-after S`` (bench_runs.py): each goal succeeds exactly ``S`` s after it arrived (a timer
of its own, not the 10 Hz tick), and the moment just before its success is sent is printed as
``succeeded <action> <x> <time.monotonic()>``, so a run's next goal can be timed from it.
"""

import argparse
import sys
import threading
import time

import actionlib
import rospy
from move_base_msgs.msg import MoveBaseAction, MoveBaseFeedback, MoveBaseResult


class MoveBase:
    """One action namespace: the goal driving now, preempted by the next."""

    def __init__(self, action, drive, succeed_after=None):
        self.action = action
        self.drive = drive if succeed_after is None else float("inf")  # the timer succeeds it, not tick()
        self.succeed_after = succeed_after
        self._lock = threading.Lock()
        self._current = None  # (goal handle, time it arrived)
        self._server = actionlib.ActionServer(action, MoveBaseAction, self._on_goal, self._on_cancel,
                                              auto_start=False)
        self._server.start()

    def _on_goal(self, handle):
        arrived = time.monotonic()
        x = handle.get_goal().target_pose.pose.position.x
        sys.stdout.write("goal {} {!r} {!r}\n".format(self.action, x, arrived))
        sys.stdout.flush()
        with self._lock:
            previous, self._current = self._current, (handle, arrived)
        if previous is not None:
            previous[0].set_canceled(MoveBaseResult(), "preempted by a new goal")
        handle.set_accepted()
        if self.succeed_after is not None:
            timer = threading.Timer(self.succeed_after, self._succeed, (handle, x))
            timer.daemon = True
            timer.start()

    def _succeed(self, handle, x):
        """``--succeed-after``: the goal (if still the current one) succeeds; the moment is printed."""
        with self._lock:
            if self._current is None or self._current[0] != handle:
                return
            self._current = None
        sent = time.monotonic()
        handle.set_succeeded(MoveBaseResult())
        sys.stdout.write("succeeded {} {!r} {!r}\n".format(self.action, x, sent))
        sys.stdout.flush()

    def _on_cancel(self, handle):
        with self._lock:
            if self._current is not None and self._current[0] == handle:
                self._current = None
        handle.set_canceled(MoveBaseResult())

    def tick(self, now):
        """Feedback for the goal under way, or its success once it has driven ``drive`` s."""
        with self._lock:
            current = self._current
            if current is not None and now - current[1] >= self.drive:
                self._current = None
        if current is None:
            return
        if now - current[1] >= self.drive:
            current[0].set_succeeded(MoveBaseResult())
        else:
            feedback = MoveBaseFeedback()
            feedback.base_position.header.frame_id = "map"
            feedback.base_position.pose.orientation.w = 1.0
            current[0].publish_feedback(feedback)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--action", action="append", default=[], help="action namespace (repeatable)")
    parser.add_argument("--drive", type=float, default=2.0, help="s a goal drives before it succeeds")
    parser.add_argument("--succeed-after", type=float, help="s after its arrival each goal succeeds (own timer)")
    opts = parser.parse_args()
    rospy.init_node("move_base_standin", disable_signals=True)
    servers = [MoveBase(action, opts.drive, opts.succeed_after) for action in opts.action or ["move_base"]]
    sys.stdout.write("ready\n")
    sys.stdout.flush()
    while not rospy.is_shutdown():
        time.sleep(0.1)
        now = time.monotonic()
        for server in servers:
            server.tick(now)


if __name__ == "__main__":
    main()
