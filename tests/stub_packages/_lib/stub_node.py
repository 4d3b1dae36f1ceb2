"""What the stand-in nodes share: finding this checkout, a latched map, a static tf, idling.

The stand-ins run under Debian's python3 as roslaunch starts them (not in the venv), so they put
the checkout on sys.path themselves to reuse the project's map reader and the scripted move_base.
"""

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
    msg = OccupancyGrid(info=meta, data=grid.cells)
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
