"""The simulated move_base's keepout layer: the mask on ``keepout_map`` laid over the map it plans on.

The simulation obeys the zones exactly when the real move_base would: the navigation mode builds
this stand-in only when the robot's own costmap configuration reads the mask
(``zones/costmap_rules.py``: a StaticLayer on the topic, ``use_maximum``, not ``first_map_only``,
before inflation), and it hears the same latched message the real costmaps hear. Each mask
(decoded from its bytes, ``maps/wire.py``) becomes the planner's costmap: every lethal cell of the
mask an obstacle of the map, inflated by the robot's radius as the map's own walls are. A mask of
another size, resolution or origin than the map is ignored, saying so (the real global costmap
would resize itself to it). The goal under way keeps its plan; the next goal plans around the zones.
"""

import logging

import rospy

from flask_move_server.maps.wire import BadMapMessage, decode
from flask_move_server.sim import costmap, occupancy, planner
from flask_move_server.zones.mask import LETHAL

log = logging.getLogger(__name__)

RECV_CHUNK = 1 << 22


class KeepoutStandIn:
    """Plans the move_base stand-in's goals on ``grid`` with the zones of each mask heard on ``topic``."""

    def __init__(self, node, topic, grid, move_base, radius, margin, plain):
        """``plain``: the planner of ``grid`` without zones (used while the mask is all free)."""
        self.topic, self.grid, self.move_base = topic, grid, move_base
        self.radius, self.margin, self.plain = radius, margin, plain
        self._sub = None
        self._closed = False
        self.masks = 0  # masks taken
        node.when_ready(self._setup)

    def _setup(self):
        if self._closed:
            return
        self._sub = rospy.Subscriber(self.topic, rospy.AnyMsg, self._on_mask, queue_size=1, buff_size=RECV_CHUNK)

    def _on_mask(self, msg):
        try:
            _, mask = decode(getattr(msg, "_buff", b""))
        except BadMapMessage as exc:
            log.warning("simulated keepout layer: ignoring a broken mask on %s: %s", self.topic, exc)
            return
        if not _same_grid(mask, self.grid):
            log.warning("simulated keepout layer: the mask on %s is %d x %d at %g m from (%g, %g), the map %d x %d at "
                        "%g m from (%g, %g): ignored", self.topic, mask.width, mask.height, mask.resolution,
                        mask.origin_x, mask.origin_y, self.grid.width, self.grid.height, self.grid.resolution,
                        self.grid.origin_x, self.grid.origin_y)
            return
        if self._closed:
            return
        self.move_base.set_planner(self._planner(mask.cells))
        self.masks += 1

    def _planner(self, cells):
        if LETHAL not in cells:
            return self.plain
        grid = self.grid
        merged = [100 if zone == LETHAL else value for value, zone in zip(grid.cells, cells)]
        kept_out = occupancy.OccupancyMap(grid.width, grid.height, grid.resolution, grid.origin_x, grid.origin_y,
                                          merged, grid.source)
        return planner.Planner(costmap.Costmap(kept_out, self.radius, self.margin), navfn_start=True)

    def close(self):
        self._closed = True
        if self._sub is not None:
            self._sub.unregister()


def _same_grid(mask, grid):
    return (mask.width, mask.height) == (grid.width, grid.height) and all(
        abs(a - b) < 1e-6 for a, b in ((mask.resolution, grid.resolution), (mask.origin_x, grid.origin_x),
                                       (mask.origin_y, grid.origin_y)))
