"""move_base's global plan as ``plan`` events, for the page to draw the way the robot will take.

Subscribes to ``navigation.plan_topic`` (nav_msgs/Path, move_base's ``NavfnROS/plan`` by
default; the sim's stand-in publishes the same) and publishes ``plan`` =
``{"frame": "map", "poses": [[x, y], …]}`` on the event bus, thinned to at most
``max_points`` points (the first and last always kept) and rounded to the millimetre, so a
long plan stays a small event. When the goal ends (the ``status`` event's navigation state
is no longer active or canceling), the plan is cleared: ``{"frame": …, "poses": []}``. An old
plan arriving while no goal is under way (a latched topic's leftover) is not told.
"""

import logging
import math

import rospy
from nav_msgs.msg import Path

log = logging.getLogger(__name__)

MAX_POINTS = 500
UNDER_WAY = ("active", "canceling")
LEFTOVER_AGE = 2.0  # s: a plan this old on arrival, no goal under way, is a latched one of an ended goal


class PlanRelay:
    """Relays the plan topic to the event bus and clears the plan when the goal ends."""

    def __init__(self, topic, events, node, max_points=MAX_POINTS):
        self._topic = topic
        self._events = events
        self._max_points = max_points
        self._subscriber = None
        self._shown = False  # a plan with poses was told and not cleared since
        self._closed = False
        events.listen("status", self._on_status)
        node.when_ready(self._setup, part="PlanRelay")

    def _setup(self):
        if not self._closed:
            self._subscriber = rospy.Subscriber(self._topic, Path, self._on_path, queue_size=1)

    def _on_path(self, msg):
        if self._closed or self._leftover(msg):
            return
        frame = msg.header.frame_id or (msg.poses[0].header.frame_id if msg.poses else "")
        points = [(p.pose.position.x, p.pose.position.y) for p in msg.poses]
        self._shown = bool(points)
        self._events.publish("plan", plan_event(frame, points, self._max_points))

    def _leftover(self, msg):
        """True for an old plan while no goal is under way: a latched topic's last message, given to
        this subscriber on (re)connecting; drawn, it would stay until the next goal ended."""
        stamp = msg.header.stamp.to_sec()
        navigation = (self._events.latest("status") or {}).get("navigation") or {}
        return bool(stamp) and navigation.get("state") not in UNDER_WAY and rospy.get_time() - stamp > LEFTOVER_AGE

    def _on_status(self, status):
        navigation = (status or {}).get("navigation") or {}
        if self._shown and navigation.get("state") not in UNDER_WAY:
            self._shown = False
            last = self._events.latest("plan") or {}
            self._events.publish("plan", {"frame": last.get("frame", ""), "poses": []})

    def close(self):
        """Stop listening to the plan topic. Idempotent."""
        self._closed = True
        subscriber, self._subscriber = self._subscriber, None
        if subscriber is not None:
            subscriber.unregister()


def plan_event(frame, points, max_points=MAX_POINTS):
    """The ``plan`` event for ``points`` [(x, y)…]: at most ``max_points``, ends kept, mm rounding."""
    return {"frame": frame, "poses": [[round(x, 3), round(y, 3)] for x, y in thin(points, max_points)]}


def thin(points, max_points):
    """Every k-th of ``points`` so at most ``max_points`` remain; the first and the last are kept."""
    points = list(points)
    if len(points) <= max_points:
        return points
    step = math.ceil((len(points) - 1) / (max_points - 1))
    kept = points[::step]
    if (len(kept) - 1) * step != len(points) - 1:  # the goal end was stepped over
        if len(kept) == max_points:
            kept.pop()
        kept.append(points[-1])
    return kept
