"""All waypoints as RViz markers: an arrow for the heading and a text label each.

Published latched on ``/waypoint_markers`` (visualization_msgs/MarkerArray), so
an RViz started later still shows them. Every array starts with a DELETEALL
marker: a removed or renamed waypoint disappears instead of lingering.
"""

import rospy
from visualization_msgs.msg import Marker, MarkerArray

from flask_move_server.ros.convert import write_pose

ARROW_NS, LABEL_NS = "waypoints", "waypoint_names"


def marker_array(waypoints, frame):
    """The MarkerArray showing ``waypoints`` (Waypoint objects) in ``frame``."""
    clear = Marker()
    clear.action = Marker.DELETEALL
    markers = [clear]
    for index, wp in enumerate(waypoints):
        markers.append(_arrow(index, wp, frame))
        markers.append(_label(index, wp, frame))
    return MarkerArray(markers=markers)


def _base(marker_type, ns, index, wp, frame):
    m = Marker()
    m.header.frame_id = frame
    m.ns, m.id, m.type, m.action = ns, index, marker_type, Marker.ADD
    m.pose.position.x, m.pose.position.y = wp.x, wp.y
    m.pose.orientation.w = 1.0
    m.color.a = 1.0
    return m


def _arrow(index, wp, frame):
    m = _base(Marker.ARROW, ARROW_NS, index, wp, frame)
    write_pose(m.pose, wp)  # a Waypoint has the x, y and yaw of a pose
    m.pose.position.z = 0.05
    m.scale.x, m.scale.y, m.scale.z = 0.5, 0.08, 0.08
    m.color.r, m.color.g, m.color.b = 0.1, 0.6, 1.0
    return m


def _label(index, wp, frame):
    m = _base(Marker.TEXT_VIEW_FACING, LABEL_NS, index, wp, frame)
    m.pose.position.z = 0.4
    m.scale.z = 0.25
    m.color.r = m.color.g = m.color.b = 1.0
    m.text = wp.name
    return m


class MarkerPublisher:
    """The latched ``/waypoint_markers`` topic, republished only when the waypoints change."""

    def __init__(self, topic, frame):
        self.frame = frame
        self._pub = rospy.Publisher(topic, MarkerArray, queue_size=1, latch=True)
        self._shown = None

    def show(self, waypoints):
        waypoints = list(waypoints)
        if waypoints == self._shown:
            return
        self._pub.publish(marker_array(waypoints, self.frame))
        self._shown = waypoints

    def close(self):
        """Withdraw the topic. Idempotent."""
        if self._pub is not None:
            self._pub.unregister()
            self._pub = None
