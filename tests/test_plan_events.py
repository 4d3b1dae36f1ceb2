"""move_base's global plan reaches the event bus as ``plan`` events (real rospy, real topic)."""

import rospy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path

from flask_move_server.core.events import EventBus
from flask_move_server.ros.plan import MAX_POINTS, PlanRelay


def _path(frame, count, age=0.0):
    msg = Path()
    msg.header.frame_id = frame
    msg.header.stamp = rospy.Time.from_sec(rospy.get_time() - age)
    for i in range(count):
        pose = PoseStamped()
        pose.header.frame_id = frame
        pose.pose.position.x = i * 0.01
        pose.pose.position.y = 1.0
        msg.poses.append(pose)
    return msg


def test_a_plan_is_told_thinned_and_cleared_when_the_goal_ends(ros_node, unique_name):
    bus = EventBus()
    sub = bus.subscribe(["plan"])
    topic = unique_name + "/move_base/NavfnROS/plan"
    relay = PlanRelay(topic, bus, ros_node)
    publisher = rospy.Publisher(topic, Path, queue_size=1, latch=True)
    try:
        publisher.publish(_path("map", 2001))
        kind, plan = sub.next(10)
        assert kind == "plan" and plan["frame"] == "map"
        assert len(plan["poses"]) <= MAX_POINTS
        assert plan["poses"][0] == [0.0, 1.0] and plan["poses"][-1] == [20.0, 1.0]
        bus.publish("status", {"navigation": {"state": "active"}})
        assert sub.next(0.2) is None  # still under way: the plan stays
        bus.publish("status", {"navigation": {"state": "succeeded"}})
        assert sub.next(1) == ("plan", {"frame": "map", "poses": []})
        bus.publish("status", {"navigation": {"state": "idle"}})
        assert sub.next(0.2) is None  # cleared once, not on every status
    finally:
        publisher.unregister()
        relay.close()
        relay.close()


def test_a_latched_plan_of_a_goal_that_ended_is_not_drawn(ros_node, unique_name):
    bus = EventBus()
    bus.publish("status", {"navigation": {"state": "succeeded"}})
    sub = bus.subscribe(["plan"])
    topic = unique_name + "/plan"
    publisher = rospy.Publisher(topic, Path, queue_size=1, latch=True)
    publisher.publish(_path("map", 10, age=30.0))  # published long ago, latched
    relay = PlanRelay(topic, bus, ros_node)
    try:
        assert sub.next(1.0) is None
        publisher.publish(_path("map", 10))  # a goal's new plan, before the status says active
        kind, plan = sub.next(10)
        assert kind == "plan" and len(plan["poses"]) == 10
    finally:
        publisher.unregister()
        relay.close()
