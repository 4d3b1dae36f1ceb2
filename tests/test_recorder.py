"""record-waypoints with a real ROS master: clicks, the robot's pose, markers, undo."""

import math

import pytest
import rospy
import yaml
from geometry_msgs.msg import PointStamped, PoseStamped, PoseWithCovarianceStamped, TransformStamped
from tf2_ros import TransformBroadcaster
from visualization_msgs.msg import Marker, MarkerArray

from flask_move_server.core.geometry import yaw_to_quaternion
from flask_move_server.recorder.markers import MarkerPublisher
from flask_move_server.recorder.ros_io import RosSide
from flask_move_server.recorder.savers import FileSaver
from flask_move_server.recorder.session import Session
from tests.conftest import wait_for


class Rig:
    """A recorder session on the test node, with its own frames and topics."""

    def __init__(self, name, waypoints_file, auto_names=False, saver=None):
        self.name = name
        self.map, self.base = name + "_map", name + "_base_link"
        self.topics = {k: "/{}/{}".format(name, k) for k in ("amcl_pose", "clicked_point", "goal", "markers")}
        self.ros = RosSide(self.map, self.base, self.topics["amcl_pose"], self.topics["clicked_point"],
                           self.topics["goal"])
        self.markers = MarkerPublisher(self.topics["markers"], self.map)
        self.said = []
        self.saver = saver or FileSaver(str(waypoints_file))
        self.session = Session(self.saver, self.ros, self.markers, say=self.said.append, auto_names=auto_names)
        self.file = waypoints_file
        self.shown = []
        self._marker_sub = rospy.Subscriber(self.topics["markers"], MarkerArray, self.shown.append)

    def file_waypoints(self):
        if not self.file.exists():
            return {}
        return (yaml.safe_load(self.file.read_text()) or {}).get("waypoints") or {}

    def publish(self, topic_key, msg_type, msg, until, message):
        """Publish ``msg`` and keep the publisher until ``until()`` (unregistering at once can drop it)."""
        pub = rospy.Publisher(self.topics[topic_key], msg_type, queue_size=10)
        try:
            wait_for(lambda: pub.get_num_connections() > 0, message="a subscriber on " + self.topics[topic_key])
            pub.publish(msg)
            wait_for(until, message=message)
        finally:
            pub.unregister()

    def click(self, x, y, frame=None):
        msg = PointStamped()
        msg.header.frame_id = self.map if frame is None else frame
        msg.point.x, msg.point.y = x, y
        self.publish("clicked_point", PointStamped, msg,
                     lambda: not self.ros.clicks.empty() or not self.ros.problems.empty(), "the click")
        self.session.handle_clicks()

    def close(self):
        self._marker_sub.unregister()
        self.markers.close()
        self.ros.close()


@pytest.fixture
def rig(ros_node, unique_name, tmp_path):
    r = Rig(unique_name, tmp_path / "waypoints.yaml")
    yield r
    r.close()


def _labels(array):
    assert array.markers[0].action == Marker.DELETEALL
    arrows = [m for m in array.markers[1:] if m.type == Marker.ARROW]
    texts = [m.text for m in array.markers if m.type == Marker.TEXT_VIEW_FACING]
    assert len(arrows) == len(texts)
    return texts


def test_a_clicked_point_becomes_a_named_waypoint_and_a_marker(rig):
    rig.session.auto_names = True
    rig.click(1.5, -2.25)
    assert rig.file_waypoints() == {"wp1": [1.5, -2.25, 0.0]}
    wait_for(lambda: rig.shown and _labels(rig.shown[-1]) == ["wp1"], message="the wp1 marker")
    arrow = [m for m in rig.shown[-1].markers[1:] if m.type == Marker.ARROW][0]
    assert (arrow.header.frame_id, arrow.pose.position.x, arrow.pose.position.y) == (rig.map, 1.5, -2.25)

    rig.click(3.0, 4.0)
    assert list(rig.file_waypoints()) == ["wp1", "wp2"]
    wait_for(lambda: _labels(rig.shown[-1]) == ["wp1", "wp2"], message="both markers")
    assert rig.said[-1].startswith("Saved wp2 at x 3.00, y 4.00")


def test_a_click_asks_for_a_name_and_nav_goal_gives_the_heading(rig):
    rig.click(2.0, 1.0)
    assert rig.said[-1] == "Publish Point at x 2.00, y 1.00, yaw 0.00. Name it (empty line skips):"
    rig.session.handle_line("living room")
    assert rig.file_waypoints() == {"living room": [2.0, 1.0, 0.0]}

    goal = PoseStamped()
    goal.header.frame_id = rig.map
    goal.pose.position.x = -1.0
    o = goal.pose.orientation
    o.x, o.y, o.z, o.w = yaw_to_quaternion(1.25)
    rig.publish("goal", PoseStamped, goal, lambda: not rig.ros.clicks.empty(), "the 2D Nav Goal")
    rig.session.handle_clicks()
    assert rig.said[-1].startswith("2D Nav Goal at x -1.00")
    rig.session.handle_line("")
    assert rig.said[-1] == "Skipped that click." and len(rig.file_waypoints()) == 1

    rig.publish("goal", PoseStamped, goal, lambda: not rig.ros.clicks.empty(), "the 2D Nav Goal again")
    rig.session.handle_clicks()
    rig.session.handle_line("door")
    assert rig.file_waypoints()["door"] == [-1.0, 0.0, pytest.approx(1.25)]


def test_list_rename_delete_undo(rig):
    rig.session.auto_names = True
    for x in (1.0, 2.0, 3.0):
        rig.click(x, 0.0)
    rig.session.handle_line('rename wp2 "front door"')
    assert list(rig.file_waypoints()) == ["wp1", "front door", "wp3"]
    rig.session.handle_line("delete wp1")
    rig.session.handle_line("delete wp9")
    assert rig.said[-1] == "No waypoint named 'wp9'. Did you mean: 'wp3'?"
    assert list(rig.file_waypoints()) == ["front door", "wp3"]
    rig.session.handle_line("list")
    assert [line.split()[0] for line in rig.said[-2:]] == ["front", "wp3"]

    rig.session.handle_line("undo")
    assert rig.said[-1] == "Undone: deleted wp1."
    assert rig.file_waypoints()["wp1"] == [1.0, 0.0, 0.0]
    rig.session.handle_line("undo")
    assert list(rig.file_waypoints()) == ["wp2", "wp3", "wp1"]  # renamed back in place; wp1 re-added last
    wait_for(lambda: sorted(_labels(rig.shown[-1])) == ["wp1", "wp2", "wp3"], message="markers after undo")
    for _ in range(3):
        rig.session.handle_line("undo")
    assert rig.file_waypoints() == {}
    rig.session.handle_line("undo")
    assert rig.said[-1] == "Nothing to undo."
    assert rig.session.handle_line("quit") is False


def test_the_current_pose_from_tf_else_amcl(rig):
    rig.session.handle_line("dock")
    assert "No '{}' frame in tf yet".format(rig.map) in rig.said[-1]
    assert rig.file_waypoints() == {}

    tf = TransformBroadcaster()

    def send(parent, child, x, y, yaw):
        t = TransformStamped()
        t.header.stamp = rospy.Time.now()
        t.header.frame_id, t.child_frame_id = parent, child
        t.transform.translation.x, t.transform.translation.y = x, y
        r = t.transform.rotation
        r.x, r.y, r.z, r.w = yaw_to_quaternion(yaw)
        tf.sendTransform(t)

    other = rig.name + "_odom_elsewhere"
    wait_for(lambda: send(rig.map, other, 0, 0, 0) or rig.ros.has_map_frame(), message="the map frame in tf")
    rig.session.handle_line("dock")
    assert "but no path to '{}'".format(rig.base) in rig.said[-1]

    amcl = PoseWithCovarianceStamped()
    amcl.header.frame_id = rig.map
    amcl.pose.pose.position.x, amcl.pose.pose.orientation.w = -3.0, 1.0
    amcl.header.stamp = rospy.Time.now() - rospy.Duration(30.0)  # AMCL stopped half a minute ago
    rig.publish("amcl_pose", PoseWithCovarianceStamped, amcl, lambda: rig.ros.pose.current() is not None,
                "the AMCL pose")
    rig.session.handle_line("here stale")
    assert "s old (from amcl_pose)" in rig.said[-1] and rig.file_waypoints() == {}

    amcl.header.stamp = rospy.Time.now()
    rig.publish("amcl_pose", PoseWithCovarianceStamped, amcl,
                lambda: rig.ros.pose.age(rig.ros.pose.current()) < 1.0, "the fresh AMCL pose")
    rig.session.handle_line("here dock")
    assert rig.file_waypoints() == {"dock": [-3.0, 0.0, 0.0]}

    def tf_pose():
        send(rig.map, rig.base, 4.0, 5.0, -math.pi / 2)
        return rig.ros.current_pose().x == 4.0

    wait_for(tf_pose, message="the tf pose")
    rig.session.handle_line("charger")
    assert rig.file_waypoints()["charger"] == [4.0, 5.0, pytest.approx(-math.pi / 2)]
    rig.session.handle_line("dock")
    assert rig.said[-1].startswith("Replaced dock at x 4.00")
    rig.session.handle_line("undo")
    assert rig.file_waypoints()["dock"] == [-3.0, 0.0, 0.0]


def test_a_click_in_another_frame_is_placed_in_the_map(rig):
    rig.session.auto_names = True
    rig.click(1.0, 0.0, frame=rig.name + "_nowhere")
    assert "set RViz's Fixed Frame to '{}'".format(rig.map) in rig.said[-1]
    assert rig.file_waypoints() == {}


def test_bad_names_change_nothing(rig):
    rig.click(1.0, 1.0)
    rig.session.handle_line("a/b")
    assert rig.said[-1].startswith("Not saved: Invalid waypoint name")
    assert rig.file_waypoints() == {}
