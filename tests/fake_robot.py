"""A robot without ROS for the web tests: the Robot facade's methods, each call recorded.

The Flask app knows only the facade (robot.py), so validation, auth, the Host/Origin guard and the
error shapes can be tested against this in milliseconds, as Flask's tutorial tests its app against
a small test database. What ROS does with a request (goals reaching move_base, velocities on
/cmd_vel, poses from tf) is tests/test_api.py's business, on the real robot.
"""

import time

from flask_move_server.core.errors import NavigationUnavailable, NoPose
from flask_move_server.drive.estop import EStop

IDLE = "idle"


class FakeRobot:
    """Answers as a connected robot with move_base ready and nothing moving.

    ``calls`` lists ``(method, args)`` in order. A goal is ``active`` until ``stop``/``teleop``
    cancel it or ``wait`` finds it ``succeeded``. The e-stop is the real latch (drive/estop.py), so
    goals and teleop are refused while it is latched, as by the real facade. ``pose``: the pose
    ``current_pose`` gives (a Pose2D), or None for a robot that does not know where it is.
    """

    move_base_ready = True  # False: goals answer 503 move_base_unavailable, as with no move_base
    goal_gate = None  # a modes/goal_gate.GoalGate admits goals first, as on the real facade

    def __init__(self, pose=None):
        self.calls = []
        self.pose = pose
        self.estop = EStop()
        self.estop.when_engaged(lambda source: self.stop())
        self._navigation = _Navigation(lambda: self.move_base_ready)

    def goto(self, goal):
        self.calls.append(("goto", goal))
        if self.goal_gate is not None:
            self.goal_gate.admit()
        if not self.move_base_ready:
            raise NavigationUnavailable("move_base does not answer on the action '/move_base'.")
        self.estop.refuse_motion("goals are")
        return self._navigation.start(goal)

    def run_goto(self, goal):
        """A run's goal (missions/executor.py): as goto, recorded as such."""
        self.calls.append(("run_goto", goal))
        self.estop.refuse_motion("goals are")
        return self._navigation.start(goal)

    def goal_end(self, seq, timeout):
        """A fake goal never ends by itself: ``active`` after ``timeout``, or how stop/teleop ended it."""
        if self._navigation.seq == seq and self._navigation.state == "active":
            time.sleep(min(timeout, 0.05))
            return "active", None
        return ("canceled" if self._navigation.seq != seq else self._navigation.state), None

    def cancel_goal(self, seq):
        if self._navigation.seq == seq:
            self._navigation.cancel()

    def halt(self):
        self.calls.append(("halt",))
        return self._navigation.cancel()

    def refuse_motion(self, what):
        self.estop.refuse_motion(what)

    def busy_with(self):
        return None

    def wait(self, seq, timeout):
        self.calls.append(("wait", seq, timeout))
        self._navigation.state = "succeeded"
        return True

    def navigation_status(self):
        return self._navigation.status()

    def engage_estop(self, source):
        self.calls.append(("engage_estop", source))
        return self.estop.engage(source)

    def release_estop(self):
        self.calls.append(("release_estop",))
        return self.estop.release()

    def estop_status(self):
        return self.estop.status()

    def stop(self):
        self.calls.append(("stop",))
        return self._navigation.cancel()

    def teleop(self, linear, angular):
        self.calls.append(("teleop", linear, angular))
        self.estop.refuse_motion("teleop is")
        result = {"linear": linear, "angular": angular, "hold": 0.5}
        if self._navigation.cancel():
            result["canceled_goal"] = True
        return result

    def current_pose(self):
        self.calls.append(("current_pose",))
        if self.pose is None:
            raise NoPose("The robot's pose is not known (fake robot).")
        return self.pose

    def moved(self):
        """The calls that would have moved a real robot (goals and teleop)."""
        return [call for call in self.calls if call[0] in ("goto", "run_goto", "teleop")]

    def status(self):
        return {
            "pose": None,
            "navigation": self._navigation.status(),
            "teleop": {"active": False, "linear": 0.0, "angular": 0.0, "remaining": None, "deadman": 0.5,
                       "max_linear": 0.4, "max_angular": 1.5},
            "motors": {"backend": "none", "left": 0.0, "right": 0.0},
            "estop": self.estop.status(),
            "battery": None,
            "ros": {"state": "connected", "master_uri": "http://fake:11311", "node": "/fake"},
        }

    def health(self):
        return {"status": "ok", "ros": "connected", "move_base": "ready"}

    def close(self):
        """Nothing to release."""


class _Navigation:
    """The goal state the facade reports (``navigation_status``)."""

    def __init__(self, move_base_ready=lambda: True):
        self.state = IDLE
        self.goal = None
        self.seq = 0
        self.server_ready = move_base_ready  # a move_base answers (the robot's move_base_ready)

    def start(self, goal):
        self.goal, self.state = goal, "active"
        self.seq += 1
        return self.seq

    def abandon(self, why, reason, seq=None):
        """Give up the goal under way, as the navigator does when its stack goes away."""
        if self.state == "active" and seq in (None, self.seq):
            self.state = "aborted"

    def cancel(self):
        """True when a goal was under way (now canceled)."""
        if self.state != "active":
            return False
        self.state = "canceled"
        return True

    def status(self):
        goal = self.goal
        return {"state": self.state, "message": None, "target": goal.target if goal else None,
                "goal": goal.pose.as_dict() if goal else None, "goal_id": self.seq or None,
                "distance_remaining": None, "interface": "action"}
