"""A scripted move_base: a real actionlib SimpleActionServer of MoveBaseAction.

Used by the server-core tests to drive each goal outcome; the simulation
(flask_move_server.sim) has the planning one. The goal's x decides the outcome:

- ``x == ABORT_X``: aborted;  ``x == REJECT_X``: rejected;
- ``x == HOLD_X``: stays active (feedback keeps coming) until canceled or replaced;
- anything else: succeeds after ``delay`` seconds, with feedback on the way.

``ignore_cancels = True`` makes it a hung move_base: a cancel is heard but never confirmed.
"""

import threading
import time

import actionlib
import rospy
from move_base_msgs.msg import MoveBaseAction, MoveBaseFeedback, MoveBaseResult

ABORT_X, REJECT_X, HOLD_X = -100.0, -200.0, -300.0


class ScriptedMoveBase:
    def __init__(self, name="move_base", delay=0.2):
        self.name = name
        self.delay = delay
        self.goals = []  # every goal received, with the monotonic time it arrived
        self._stopping = False
        self.ignore_cancels = False
        self._server = actionlib.SimpleActionServer(name, MoveBaseAction, execute_cb=self._execute, auto_start=False)
        self._server.start()
        self._lock = threading.Lock()

    def _execute(self, goal):
        with self._lock:
            self.goals.append((time.monotonic(), goal))
        x = goal.target_pose.pose.position.x
        if x == REJECT_X:
            # SimpleActionServer accepts before execute; reject-on-arrival looks like an abort with text.
            self._server.set_aborted(MoveBaseResult(), "rejected by stand-in")
            return
        if x == ABORT_X:
            self._server.set_aborted(MoveBaseResult(), "no path")
            return
        deadline = time.monotonic() + (3600 if x == HOLD_X else self.delay)
        while time.monotonic() < deadline:
            preempt = self._server.is_preempt_requested() and not self.ignore_cancels
            if preempt or rospy.is_shutdown() or self._stopping:
                self._server.set_preempted()
                return
            feedback = MoveBaseFeedback()
            feedback.base_position = goal.target_pose
            self._server.publish_feedback(feedback)
            time.sleep(0.02)
        self._server.set_succeeded(MoveBaseResult())

    @property
    def executing(self):
        """True while a goal is being driven (active or being preempted)."""
        return self._server.is_active()

    def shutdown(self):
        """Stop serving: the action's topics are freed and the executor thread ends."""
        server = self._server
        self._stopping = True
        with server.terminate_mutex:
            server.need_to_terminate = True
        with server.execute_condition:
            server.execute_condition.notify_all()
        if server.execute_thread is not None:
            server.execute_thread.join(5)
        server.action_server.stop()
