"""Following a planned path with velocity commands: the local planner of the move_base stand-in.

A carrot follower for a differential robot: steer at the next path corner
(turning in place first when it lies far off the heading), slow down towards
the goal, then turn in place to the goal's yaw. It asks for no more than the
base can do and never for less than ``min_linear``/``min_angular`` while it
still has to move (a DC motor below its deadband does not turn at all).
Pure: no rospy; fed with poses, it returns velocities.
"""

import math
from dataclasses import dataclass

from flask_move_server.core.geometry import clamp, normalize_angle

FOLLOW, TURN_TO_GOAL, DONE = "follow", "turn_to_goal", "done"


@dataclass
class FollowerLimits:
    """Speeds and tolerances of the path follower (m, rad, m/s, rad/s)."""

    max_linear: float = 0.3
    max_angular: float = 1.2
    min_linear: float = 0.05
    min_angular: float = 0.3
    xy_goal_tolerance: float = 0.1
    yaw_goal_tolerance: float = 0.2
    corner_reach: float = 0.2       # a path corner counts as passed this close
    turn_in_place: float = 0.8      # rad: turn on the spot above this heading error
    gain_linear: float = 1.0        # (m/s) per m to the goal
    gain_angular: float = 2.0       # (rad/s) per rad of heading error

    @classmethod
    def from_planner(cls, planner):
        """The robot's own DWA limits (a ``dwa.PlannerLimits``): its speeds, minimums and tolerances."""
        return cls(max_linear=planner.max_vel_x, max_angular=planner.max_vel_theta,
                   min_linear=planner.min_vel_trans, min_angular=planner.min_vel_theta,
                   xy_goal_tolerance=planner.xy_goal_tolerance, yaw_goal_tolerance=planner.yaw_goal_tolerance)


class PathFollower:
    """Turns poses into (linear, angular) commands along one path to one goal."""

    def __init__(self, path, goal_yaw, limits):
        self.path = list(path)
        self.goal_yaw = goal_yaw
        self.limits = limits
        self.state = FOLLOW
        self._next = 1 if len(self.path) > 1 else 0

    @property
    def goal(self):
        return self.path[-1]

    def command(self, pose):
        """The velocity to apply at ``pose`` (a Pose2D); (0, 0) once the goal pose is reached."""
        lim = self.limits
        dist = self._distance(pose, self.goal)
        if self.state == FOLLOW and dist < lim.xy_goal_tolerance * 0.5:
            self.state = TURN_TO_GOAL
        elif self.state != FOLLOW and dist > lim.xy_goal_tolerance * 0.9:
            self.state = FOLLOW  # pushed off the goal: drive back
        if self.state == FOLLOW:
            return self._follow(pose, dist)
        error = normalize_angle(self.goal_yaw - pose.yaw)
        if abs(error) < lim.yaw_goal_tolerance * 0.5:
            self.state = DONE
            return 0.0, 0.0
        self.state = TURN_TO_GOAL
        return 0.0, self._turn(error)

    def remaining(self, pose):
        """The points still to drive from ``pose``: where the robot is, then the corners not yet passed."""
        return [(pose.x, pose.y)] + self.path[self._next:]

    def reached(self, pose):
        """True when ``pose`` is within the goal tolerances."""
        lim = self.limits
        dist = self._distance(pose, self.goal)
        yaw_error = abs(normalize_angle(self.goal_yaw - pose.yaw))
        return dist <= lim.xy_goal_tolerance and yaw_error <= lim.yaw_goal_tolerance

    def _follow(self, pose, dist_to_goal):
        lim = self.limits
        while self._next < len(self.path) - 1 and self._distance(pose, self.path[self._next]) < lim.corner_reach:
            self._next += 1
        tx, ty = self.path[self._next]
        error = normalize_angle(math.atan2(ty - pose.y, tx - pose.x) - pose.yaw)
        if abs(error) > lim.turn_in_place:
            return 0.0, self._turn(error)
        speed = min(lim.max_linear, lim.gain_linear * dist_to_goal) * max(0.0, math.cos(error))
        return max(lim.min_linear, speed), clamp(lim.gain_angular * error, lim.max_angular)

    def _turn(self, error):
        lim = self.limits
        rate = min(lim.max_angular, max(lim.min_angular, lim.gain_angular * abs(error)))
        return math.copysign(rate, error)

    @staticmethod
    def _distance(pose, point):
        return math.hypot(point[0] - pose.x, point[1] - pose.y)
