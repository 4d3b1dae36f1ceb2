"""What the stand-in nodes share: finding this checkout, a latched map, a static tf, idling.

The stand-ins run under Debian's python3 as roslaunch starts them (not in the venv), so they put
the checkout on sys.path themselves to reuse the project's map reader and the scripted move_base.
"""

import array
import os
import signal
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)


def idle():
    """A node that only has to exist (no ROS): wait for roslaunch's SIGINT, exit 0 on it."""
    signal.signal(signal.SIGINT, lambda *_: sys.exit(0))
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    while True:
        signal.pause()


def init(name):
    """rospy.init_node with roslaunch's remappings (``__name:=`` etc. come in argv)."""
    import rospy

    rospy.init_node(name)
    return rospy


def publish_map(grid, frame="map"):
    """Latch ``grid`` (a maps.mapfile.Grid) on ``map`` and ``map_metadata`` as map_server does."""
    import rospy
    from nav_msgs.msg import MapMetaData, OccupancyGrid

    meta = MapMetaData(resolution=grid.resolution, width=grid.width, height=grid.height)
    meta.origin.position.x, meta.origin.position.y = grid.origin_x, grid.origin_y
    meta.origin.orientation.w = 1.0
    # int8[] takes signed numbers: as bytes, an unknown cell (-1, byte 255) fails to serialize, and
    # a subscriber (move_base's static layer) gets no map at all
    msg = OccupancyGrid(info=meta, data=array.array("b", bytes(grid.cells)))
    msg.header.frame_id = frame
    msg.header.stamp = meta.map_load_time = rospy.Time.now()
    publishers = [rospy.Publisher("map", OccupancyGrid, queue_size=1, latch=True),
                  rospy.Publisher("map_metadata", MapMetaData, queue_size=1, latch=True)]
    publishers[0].publish(msg)
    publishers[1].publish(meta)
    return publishers


def static_tf(parent, child):
    """Latch an identity transform ``parent`` -> ``child`` on /tf_static."""
    import rospy
    import tf2_ros
    from geometry_msgs.msg import TransformStamped

    t = TransformStamped()
    t.header.stamp, t.header.frame_id, t.child_frame_id = rospy.Time.now(), parent, child
    t.transform.rotation.w = 1.0
    broadcaster = tf2_ros.StaticTransformBroadcaster()
    broadcaster.sendTransform(t)
    return broadcaster


def report_inputs(scan_topic="scan", links=(), odom_topic=None, seconds=3.0):
    """Listen as the real node would, then set ``~inputs``: what it would have had to work with.

    The real AMCL, gmapping and move_base need ``/scan`` arriving (gmapping: with the same beam
    count every time), the tf links ``links`` at each scan's stamp (``"@scan"`` stands for the
    scan's own frame), and DWA the velocity on ``odom_topic``. After ``seconds`` of listening the
    result lands on the parameter server as ``~inputs`` for the tests to read.
    """
    import threading
    import time

    import rospy
    import tf2_ros
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan

    buffer = tf2_ros.Buffer(cache_time=rospy.Duration(10.0))
    heard = {"scan": [], "odom": [], "listener": tf2_ros.TransformListener(buffer)}
    subs = [rospy.Subscriber(scan_topic, LaserScan, lambda m: heard["scan"].append((time.monotonic(), m)))]
    if odom_topic:
        subs.append(rospy.Subscriber(odom_topic, Odometry, lambda m: heard["odom"].append((time.monotonic(), m))))

    def rate(samples):
        return (len(samples) - 1) / (samples[-1][0] - samples[0][0]) if len(samples) > 1 else 0.0

    def link(parent, child, scan):
        child = scan.header.frame_id if child == "@scan" else child
        try:
            buffer.lookup_transform(parent, child, scan.header.stamp, rospy.Duration(0.5))
            return True
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException) as exc:
            return "{} -> {}: {}".format(parent, child, exc)

    def report():
        time.sleep(seconds)
        scans = list(heard["scan"])
        inputs = {"scans": len(scans), "scan_rate": rate(scans), "odom_rate": rate(list(heard["odom"]))}
        if scans:
            last = scans[-1][1]
            inputs.update(scan_frame=last.header.frame_id, beams=sorted({len(m.ranges) for _, m in scans}),
                          range_max=last.range_max,
                          links={"{} -> {}".format(p, c): link(p, c, last) for p, c in links})
        rospy.set_param("~inputs", inputs)

    threading.Thread(target=report, daemon=True).start()
    return heard, subs
