"""The move_base stand-in: a real actionlib server of ``move_base_msgs/MoveBaseAction``.

Each goal is checked and planned at once (a goal outside the map, in an
obstacle or walled off is aborted within a planning time, not after a
timeout), then followed by publishing ``cmd_vel``, the same topic real
move_base's local planner feeds to the base controller. Feedback carries the
localized pose. The goal succeeds once the robot stands still within
``xy_goal_tolerance`` and ``yaw_goal_tolerance``; a cancel (or a newer goal)
preempts it, and a robot that stops making progress aborts it. Goals on
``move_base_simple/goal`` are forwarded to the action, as move_base does.

It drives as the robot's DWA would, by the robot's own files (``dwa.PlannerLimits``
from move_base.yaml and dwa_local_planner.yaml): at move_base's ``controller_frequency``,
within DWA's top speeds and goal tolerances, and each command one of the velocities DWA
may choose from the current ``/odom`` velocity (``dwa.nearest``). Where DWA would find
no valid velocity for ``controller_patience``, the goal is aborted with the reason, as
the real move_base aborts after its recoveries: a configuration that cannot drive the
robot does not drive the simulation either.

Every plan is published as a ``nav_msgs/Path`` in the map frame on
``plan_topic`` (navfn's ``move_base/NavfnROS/plan``). The planner can be
swapped (``set_planner``: the known map in navigation mode, the growing SLAM
map in mapping mode); a planner that can tell when its map grew an obstacle
across the path (``path_blocked``, the SLAM map's) is asked once a second
of simulated time while the robot drives, and the path is planned again if so, as move_base does
on its growing costmap. ``withdraw()`` takes the action server away entirely
(idle mode: to the server it looks like no move_base at all) and ``serve()``
brings a new one up.
"""

import logging
import math
import threading
import time

import actionlib
import rospy
from geometry_msgs.msg import PoseStamped, Twist
from move_base_msgs.msg import MoveBaseAction, MoveBaseActionGoal, MoveBaseFeedback, MoveBaseResult
from nav_msgs.msg import Odometry, Path

from flask_move_server.core.errors import PlanningFailed
from flask_move_server.ros import own_topics
from flask_move_server.ros.convert import path_message, pose_from_msg, pose_stamped, twist
from flask_move_server.sim import dwa
from flask_move_server.sim.follower import DONE, FollowerLimits, PathFollower
from flask_move_server.sim.watches import ProgressWatch, ReplanWatch

log = logging.getLogger(__name__)

REPLAN_CHECK_PERIOD = 1.0  # simulated s between "is the path still free on the grown map?" checks
MIN_REPLAN_CHECK_PERIOD = 0.25  # real s (x speed_factor: simulated): a fast sim checks no more often (40-70 ms)
SETTLE = 0.3  # simulated s at rest at the path's end before the goal is judged


class MoveBaseStandIn:
    """Plans on the simulated map and drives the real base controller along the path."""

    def __init__(self, sim_config, action, cmd_vel_topic, simple_goal_topic, frames, node, planner, limits,
                 pose_source, plan_topic=None, serve=True, odom_topic="odom", *, clock):
        """``clock()``: the simulated world's time in seconds (``SimWorld.clock.now``), which the timers count."""
        self.config = sim_config
        self.action = action
        self.frames = frames
        self.planner = planner
        self.limits = limits  # dwa.PlannerLimits: the robot's own local planner configuration
        self.pose = pose_source
        self.clock = clock
        self._topics = (cmd_vel_topic, simple_goal_topic, plan_topic, odom_topic)
        self._velocity = (0.0, 0.0)  # the base's (linear, angular) from /odom: where DWA's window is centred
        self._lock = threading.Lock()
        self._serving = serve
        self._endpoint = None
        self._cmd_vel = None
        self._closed = threading.Event()
        self.goals = 0  # goals taken, goals ended and how the last one ended: (outcome, text)
        self.ended = 0
        self.last_outcome = None
        self.plans = 0
        node.when_ready(self._setup)

    def _setup(self):
        cmd_vel_topic, simple_goal_topic, plan_topic, odom_topic = self._topics
        with self._lock:
            if self._closed.is_set():
                return
            self._cmd_vel = rospy.Publisher(cmd_vel_topic, Twist, queue_size=1, tcp_nodelay=True)
            self._odom_sub = rospy.Subscriber(odom_topic, Odometry, self._on_odom, queue_size=1, tcp_nodelay=True)
            self._forward = rospy.Publisher(self.action + "/goal", MoveBaseActionGoal, queue_size=1)
            self._plan_pub = rospy.Publisher(plan_topic, Path, queue_size=1, latch=True) if plan_topic else None
            self._simple_sub = rospy.Subscriber(simple_goal_topic, PoseStamped, self._on_simple_goal, queue_size=1)
            if self._serving:
                self._endpoint = _Endpoint(self.action, self._execute)
        log.info("move_base stand-in %s the action %s", "serving" if self._serving else "not serving",
                 rospy.resolve_name(self.action))

    def set_planner(self, planner):
        """Plan the next goals on ``planner`` (a goal under way keeps the one it started with)."""
        self.planner = planner

    @property
    def serving(self):
        """True while the action server is up (or will be, once the node connects)."""
        return self._serving and not self._closed.is_set()

    def serve(self):
        """Bring the action server up (at once, or when the node connects). Idempotent."""
        with self._lock:
            self._serving = True
            if self._cmd_vel is not None and self._endpoint is None and not self._closed.is_set():
                self._endpoint = _Endpoint(self.action, self._execute)

    def wait_clients(self, timeout):
        """Block until every action client the master knows of is connected to the action server.

        ``start()`` of a mode returns once this holds (or ``timeout`` passed), so the server's
        navigator takes a goal right after the switch instead of answering 503 for ~30 ms.
        True when connected (or when nobody is a client); False after ``timeout``.
        """
        with self._lock:
            endpoint = self._endpoint
        if endpoint is None:
            return False
        if not endpoint.has_clients():
            return True
        deadline = time.monotonic() + timeout
        while not endpoint.clients_connected():
            if time.monotonic() > deadline or self._closed.is_set():
                return False
            time.sleep(0.005)
        return True

    def withdraw(self):
        """Take the action server away: the goal under way is aborted, then every action topic goes."""
        with self._lock:
            self._serving = False
            endpoint, self._endpoint = self._endpoint, None
        if endpoint is not None:
            endpoint.close()

    def _on_odom(self, msg):
        twist = msg.twist.twist
        self._velocity = (twist.linear.x, twist.angular.z)

    def _on_simple_goal(self, msg):
        goal = MoveBaseActionGoal()
        goal.header.stamp = rospy.Time.now()
        goal.goal_id.stamp = goal.header.stamp
        goal.goal_id.id = "move_base_simple-{}".format(time.monotonic())
        goal.goal.target_pose = msg
        self._forward.publish(goal)

    # one goal ---------------------------------------------------------------------

    def _execute(self, endpoint, goal):
        self.goals += 1
        target = goal.target_pose
        server = endpoint.server
        try:
            follower = self._plan(target)
        except PlanningFailed as exc:
            log.warning("move_base stand-in: aborting the goal: %s", exc)
            self._ended("aborted", str(exc))
            server.set_aborted(MoveBaseResult(), str(exc))
            return
        try:
            outcome, text = self._follow(endpoint, follower, target)
        except PlanningFailed as exc:
            outcome, text = "aborted", str(exc)
        self._publish_velocity(0.0, 0.0)
        log.info("move_base stand-in: goal %s (%s)", outcome, text)
        self._ended(outcome, text)
        if outcome == "succeeded":
            server.set_succeeded(MoveBaseResult(), text)
        elif outcome == "preempted":
            server.set_preempted(MoveBaseResult(), text)
        else:
            server.set_aborted(MoveBaseResult(), text)

    def _ended(self, outcome, text):
        self.last_outcome = (outcome, text)
        self.ended += 1

    def _plan(self, target, planner=None):
        frame = target.header.frame_id.lstrip("/")
        if frame not in ("", self.frames.map):
            raise PlanningFailed("frame", "goal in frame {!r}: the simulator plans in {!r}".format(
                frame, self.frames.map))
        p, o = target.pose.position, target.pose.orientation
        norm = math.sqrt(o.x * o.x + o.y * o.y + o.z * o.z + o.w * o.w)
        if not all(math.isfinite(v) for v in (p.x, p.y, norm)) or abs(norm - 1.0) > 0.01:
            raise PlanningFailed("invalid", "the goal's position or orientation quaternion is invalid")
        here = self.pose()
        path = (planner or self.planner).plan((here.x, here.y), (p.x, p.y))
        self._publish_plan(path)
        return PathFollower(path, pose_from_msg(target.pose).yaw, FollowerLimits.from_planner(self.limits))

    def _follow(self, endpoint, follower, target):
        """Drive along the path until reached, preempted or stuck: (outcome, text).

        The loop runs on real time (``controller_frequency`` times ``speed_factor``); its timers count
        the simulated world's time (``self.clock``), as the real move_base's ``controller_patience``,
        ``planner_patience`` and ``oscillation_timeout`` count ROS time, the simulator's ``/clock``
        under ``use_sim_time``: on a loaded machine the world falls behind real time and the robot
        makes less progress per real second, and the watchdogs wait as many real seconds longer.
        """
        factor = self.config.speed_factor
        period = max(0.01, 1.0 / (self.limits.move_base_frequency * factor))  # at most 100 Hz, however fast
        clock = self.clock
        stuck = ProgressWatch(self.config.stuck_timeout)
        replan = ReplanWatch(self.planner, max(MIN_REPLAN_CHECK_PERIOD * factor, REPLAN_CHECK_PERIOD), clock())
        settle_until = no_velocity_since = None
        while not rospy.is_shutdown() and not self._closed.is_set() and not endpoint.withdrawn.is_set():
            if endpoint.server.is_preempt_requested():
                return "preempted", "canceled"
            pose, now = self.pose(), clock()
            if replan.due(follower.remaining(pose), now):
                log.info("move_base stand-in: an obstacle seen across the path: planning again")
                follower = self._plan(target, replan.planner)
            command = self._local_plan(follower.command(pose), follower.state == DONE)
            if command is None:  # DWA: no valid trajectory; move_base brakes, then recovers or aborts
                no_velocity_since = now if no_velocity_since is None else no_velocity_since
                if now - no_velocity_since > self.limits.controller_patience:
                    return "aborted", self._no_trajectory_reason()
            else:
                no_velocity_since = None
            self._publish_velocity(*(command or (0.0, 0.0)))
            self._feedback(endpoint.server, target, pose)
            if follower.state == DONE:
                settle_until = now + SETTLE if settle_until is None else settle_until
                if now >= settle_until and follower.reached(self.pose()):
                    return "succeeded", "reached the goal"
            else:
                settle_until = None
            if stuck.stalled(pose, now):
                return "aborted", "the robot made no progress for {} s".format(self.config.stuck_timeout)
            endpoint.withdrawn.wait(period)  # a withdrawal (mode switch) ends the goal at once, not a period later
        return "aborted", "the navigation stack stopped"

    def _local_plan(self, wanted, stopping):
        """The velocity DWA would send for ``wanted``: the nearest it may choose; None if it may choose none.

        Stopping at the goal is DWA's stop-and-rotate controller, which brakes without sampling.
        """
        if stopping or wanted == (0.0, 0.0):
            return 0.0, 0.0
        return dwa.nearest(self.limits, wanted, self._velocity)

    def _no_trajectory_reason(self):
        at_rest = self._velocity == (0.0, 0.0)
        reason = dwa.why_stuck_at_rest(self.limits) if at_rest else None
        text = reason or "the local planner found no valid velocity from {:.2f} m/s, {:.2f} rad/s".format(
            *self._velocity)
        log.warning("move_base stand-in: %s", text)
        return "no valid trajectory for {} s (controller_patience): {}".format(self.limits.controller_patience, text)

    def _publish_velocity(self, linear, angular):
        self._cmd_vel.publish(twist(linear, angular))

    def _publish_plan(self, points):
        self.plans += 1
        if self._plan_pub is not None:
            self._plan_pub.publish(path_message(points, self.frames.map, rospy.Time.now()))

    def _feedback(self, server, target, pose):
        feedback = MoveBaseFeedback()
        feedback.base_position = pose_stamped(pose, self.frames.map, rospy.Time.now())
        server.publish_feedback(feedback)

    def close(self):
        """End the goal under way (aborted), stop taking goals. Idempotent."""
        with self._lock:
            if self._closed.is_set():
                return
            self._closed.set()
            endpoint, self._endpoint = self._endpoint, None
            ready = self._cmd_vel is not None
        if endpoint is not None:
            endpoint.close()
        if ready:
            self._simple_sub.unregister()
            self._odom_sub.unregister()
            for pub in (self._forward, self._plan_pub):
                if pub is not None:
                    pub.unregister()


class _Endpoint:
    """One life of the action server: up in navigation and mapping modes, gone in idle.

    actionlib's SimpleActionServer has no way to stop: its execute thread and
    its ActionServer's status timer run until rospy shuts down. Closing ends
    both (the goal under way first: ``withdrawn`` makes the stand-in abort it),
    then unregisters every action topic, so clients see the server gone.
    """

    def __init__(self, action, execute):
        self.withdrawn = threading.Event()
        for topic in ("status", "result", "feedback"):  # the server's navigator hears this life, not the last
            own_topics.forget_own_connections(rospy.resolve_name(action + "/" + topic))
        self.server = actionlib.SimpleActionServer(action, MoveBaseAction, execute_cb=lambda goal: execute(self, goal),
                                                   auto_start=False)
        self.server.start()

    def has_clients(self):
        """True when the master knows a node publishing goals to this action (a client)."""
        _, _, (publishers, _, _) = rospy.get_master().getSystemState()
        goal_topic = self.server.action_server.goal_sub.resolved_name
        return any(topic == goal_topic and nodes for topic, nodes in publishers)

    def clients_connected(self):
        """True when each topic of the action has a connection (clients heard the server)."""
        actions = self.server.action_server
        topics = (actions.goal_sub, actions.cancel_sub, actions.status_pub, actions.result_pub, actions.feedback_pub)
        return all(t.get_num_connections() > 0 for t in topics)

    def close(self):
        self.withdrawn.set()
        server = self.server
        with server.terminate_mutex:
            server.need_to_terminate = True
        with server.execute_condition:
            server.execute_condition.notify()
        if server.execute_thread is not threading.current_thread():
            server.execute_thread.join(timeout=5)
        actions = server.action_server
        timer = actions.status_timer
        if timer is not None:  # stopped and joined first: it must not publish on unregistered topics
            timer.shutdown()
            timer.join(timeout=2)
        time.sleep(0.05)  # the aborted goal's result is still in the publisher's queue
        actions.stop()
