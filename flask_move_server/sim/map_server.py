"""map_server's stand-in: one occupancy map published latched on ``/map`` and ``/map_metadata``.

The simulation's navigation mode serves the map the robot navigates on with it:
the simulated world's own map, or a map saved while mapping. Closing it takes
the topics away, as stopping map_server does (idle and mapping modes publish
no known map: a late subscriber then hears nothing). The topics are published
with ``ros/own_topics.py``: the server's own map reader, in this process, hears
each new map server even when it was still busy with the last one's map.
"""

import logging
import threading

import rospy
from nav_msgs.msg import MapMetaData, OccupancyGrid

from flask_move_server.ros import convert, own_topics

log = logging.getLogger(__name__)


class MapServerStandIn:
    """Publishes ``grid`` (an :class:`~flask_move_server.sim.occupancy.OccupancyMap`) once, latched."""

    def __init__(self, node, grid, frame, topic="map"):
        self.grid = grid
        self.frame = frame
        self.topic = topic
        self._lock = threading.Lock()
        self._pubs = None
        self._closed = False
        node.when_ready(self._setup)

    def _setup(self):
        msg = occupancy_grid_message(self.grid, self.frame)
        with self._lock:
            if self._closed:
                return
            self._pubs = (own_topics.publisher(self.topic, OccupancyGrid, queue_size=1, latch=True),
                          own_topics.publisher(self.topic + "_metadata", MapMetaData, queue_size=1, latch=True))
            self._pubs[0].publish(msg)
            self._pubs[1].publish(msg.info)
        log.info("map server stand-in: %s (%d x %d cells) on %s", self.grid.source, self.grid.width,
                 self.grid.height, rospy.resolve_name(self.topic))

    def close(self):
        """Stop serving the map. Idempotent."""
        with self._lock:
            self._closed = True
            pubs, self._pubs = self._pubs, None
        for pub in pubs or ():
            pub.unregister()


def occupancy_grid_message(grid, frame):
    """The map as a nav_msgs/OccupancyGrid (cell values clamped to -1..100)."""
    return convert.occupancy_grid(frame, rospy.Time.now(), grid.resolution, grid.width, grid.height,
                                  grid.origin_x, grid.origin_y, [v if -1 <= v <= 100 else 100 for v in grid.cells])
