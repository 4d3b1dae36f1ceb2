"""The move_base stand-in: a real actionlib server of ``move_base_msgs/MoveBaseAction``.

Each goal is checked and planned at once (a goal outside the map, in an
obstacle or walled off is aborted within a planning time, not after a
timeout), then followed by publishing ``cmd_vel``, the same topic real
move_base's local planner feeds to the base controller. Feedback carries the
localized pose. The goal succeeds once the robot stands still within
``xy_goal_tolerance`` and ``yaw_goal_tolerance``; a cancel (or a newer goal)
preempts it, and a robot that stops making progress aborts it. Goals on
``move_base_simple/goal`` are forwarded to the action, as move_base does.
"""

import logging
import math
import threading
import time

import actionlib
import rospy
from geometry_msgs.msg import PoseStamped, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseActionGoal, MoveBaseFeedback, MoveBaseResult

from flask_move_server.errors import PlanningFailed
from flask_move_server.geometry import normalize_angle
from flask_move_server.ros.convert import pose_from_msg, pose_stamped, twist
from flask_move_server.sim.follower import DONE, PathFollower

log = logging.getLogger(__name__)


class MoveBaseStandIn:
    """Plans on the simulated map and drives the real base controller along the path."""

    def __init__(self, sim_config, action, cmd_vel_topic, simple_goal_topic, frames, node, planner, limits,
                 pose_source):
        self.config = sim_config
        self.action = action
        self.frames = frames
        self.planner = planner
        self.limits = limits
        self.pose = pose_source
        self._topics = (cmd_vel_topic, simple_goal_topic)
        self._server = None
        self._closed = threading.Event()
        self.goals = 0
        node.when_ready(self._setup)

    def _setup(self):
        if self._closed.is_set():
            return
        cmd_vel_topic, simple_goal_topic = self._topics
        self._cmd_vel = rospy.Publisher(cmd_vel_topic, Twist, queue_size=1, tcp_nodelay=True)
        self._forward = rospy.Publisher(self.action + "/goal", MoveBaseActionGoal, queue_size=1)
        self._simple_sub = rospy.Subscriber(simple_goal_topic, PoseStamped, self._on_simple_goal, queue_size=1)
        self._server = actionlib.SimpleActionServer(self.action, MoveBaseAction, execute_cb=self._execute,
                                                    auto_start=False)
        self._server.start()
        log.info("move_base stand-in serving the action %s", rospy.resolve_name(self.action))

    def _on_simple_goal(self, msg):
        goal = MoveBaseActionGoal()
        goal.header.stamp = rospy.Time.now()
        goal.goal_id.stamp = goal.header.stamp
        goal.goal_id.id = "move_base_simple-{}".format(time.monotonic())
        goal.goal.target_pose = msg
        self._forward.publish(goal)

    # one goal ---------------------------------------------------------------------

    def _execute(self, goal):
        self.goals += 1
        target = goal.target_pose
        try:
            follower = self._plan(target)
        except PlanningFailed as exc:
            log.warning("move_base stand-in: aborting the goal: %s", exc)
            self._server.set_aborted(MoveBaseResult(), str(exc))
            return
        outcome, text = self._follow(follower, target)
        self._publish_velocity(0.0, 0.0)
        log.info("move_base stand-in: goal %s (%s)", outcome, text)
        if outcome == "succeeded":
            self._server.set_succeeded(MoveBaseResult(), text)
        elif outcome == "preempted":
            self._server.set_preempted(MoveBaseResult(), text)
        else:
            self._server.set_aborted(MoveBaseResult(), text)

    def _plan(self, target):
        frame = target.header.frame_id.lstrip("/")
        if frame not in ("", self.frames.map):
            raise PlanningFailed("frame", "goal in frame {!r}: the simulator plans in {!r}".format(
                frame, self.frames.map))
        p, o = target.pose.position, target.pose.orientation
        norm = math.sqrt(o.x * o.x + o.y * o.y + o.z * o.z + o.w * o.w)
        if not all(math.isfinite(v) for v in (p.x, p.y, norm)) or abs(norm - 1.0) > 0.01:
            raise PlanningFailed("invalid", "the goal's position or orientation quaternion is invalid")
        here = self.pose()
        path = self.planner.plan((here.x, here.y), (p.x, p.y))
        return PathFollower(path, pose_from_msg(target.pose).yaw, self.limits)

    def _follow(self, follower, target):
        """Drive along the path until reached, preempted or stuck: (outcome, text)."""
        factor = self.config.speed_factor
        period = max(0.01, 1.0 / (self.config.control_rate * factor))  # at most 100 Hz, however fast the sim
        stuck = _ProgressWatch(self.config.stuck_timeout / factor)
        settle_until = None
        while not rospy.is_shutdown() and not self._closed.is_set():
            if self._server.is_preempt_requested():
                return "preempted", "canceled"
            pose = self.pose()
            linear, angular = follower.command(pose)
            self._publish_velocity(linear, angular)
            self._feedback(target, pose)
            if follower.state == DONE:
                settle_until = settle_until or time.monotonic() + 0.3 / factor
                if time.monotonic() >= settle_until and follower.reached(self.pose()):
                    return "succeeded", "reached the goal"
            else:
                settle_until = None
            if stuck.stalled(pose, time.monotonic()):
                return "aborted", "the robot made no progress for {} s".format(self.config.stuck_timeout)
            time.sleep(period)
        return "aborted", "shutting down"

    def _publish_velocity(self, linear, angular):
        self._cmd_vel.publish(twist(linear, angular))

    def _feedback(self, target, pose):
        feedback = MoveBaseFeedback()
        feedback.base_position = pose_stamped(pose, self.frames.map, rospy.Time.now())
        self._server.publish_feedback(feedback)

    def close(self):
        """End the goal under way (aborted), stop taking goals. Idempotent."""
        if self._closed.is_set():
            return
        self._closed.set()
        if self._server is None:
            return
        self._simple_sub.unregister()
        # actionlib servers have no stop(): stop listening; the result topics stay for the last answer.
        for attr in ("goal_sub", "cancel_sub"):
            topic = getattr(self._server.action_server, attr, None)
            if topic is not None:
                topic.unregister()


class _ProgressWatch:
    """Tells when the robot has not moved (1 cm or 3 degrees) for ``timeout`` seconds."""

    def __init__(self, timeout):
        self.timeout = timeout
        self._anchor = None
        self._since = None

    def stalled(self, pose, now):
        if self._anchor is None or (
            pose.distance_to(self._anchor) > 0.01 or abs(normalize_angle(pose.yaw - self._anchor.yaw)) > 0.05
        ):
            self._anchor, self._since = pose, now
            return False
        return now - self._since > self.timeout

