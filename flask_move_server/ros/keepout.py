"""The keepout mask on ``keepout_map``: the active map's enabled zones as the costmaps read them.

A latched ``nav_msgs/OccupancyGrid`` with the map's own header and ``MapMetaData``, copied byte
for byte from the map message (``MapSource.raw``), so a costmap's second ``StaticLayer``
(``keepout_layer``, config/costmap_zones.yaml) never resizes the costmap to a grid that differs
from the map by a float's last bit (static_layer.cpp ``incomingMap`` resizes a non-rolling costmap
to any map whose size, resolution or origin differ); cells LETHAL (100) in zones, FREE (0)
elsewhere (``zones/mask.py``). The message is serialized here once per change, not by genpy
(its ``int8[]`` packing of a 16 M-cell map holds 16 M Python ints).

A ``StaticLayer`` waits in move_base's start-up until its topic has a message, so a mask, all
free when there are no zones, is published as soon as a map is: without it the real move_base
never starts. Published in navigation only (or when the modes are off: the stack is not ours):
mapping's costmaps have no keepout layer (move_base.launch loads config/costmap_zones.yaml in
navigation only), as gmapping's map grows under them. When the map goes (a mode switch), the
topic goes with it, so the next stack's move_base does not read the last map's mask. ``PERIOD``:
how often the map's version, the zones' version and the robot's pose are looked at; a change is published within it.
"""

import logging
import struct
import threading

import rospy
from nav_msgs.msg import OccupancyGrid

from flask_move_server.ros import own_topics
from flask_move_server.zones import TOPIC, mask

log = logging.getLogger(__name__)

PERIOD = 0.2  # s
INFO_BYTES = 76  # MapMetaData: time (2 x uint32), float32 resolution, uint32 width, height, Pose (7 x float64)
MODES = (None, "navigation")  # the mask is published in these modes (None: the modes are off)


class KeepoutPublisher:
    """Publishes the mask of the zones on ``topic`` when the map, the zones or what the robot stands in change."""

    def __init__(self, node, store, source, guard, pose, topic=TOPIC, events=None):
        """``pose()``: the robot's Pose2D in the map frame, or None; ``guard``: a zones.guard.ZoneGuard."""
        self.topic = topic
        self._node, self._store, self._source, self._guard, self._pose = node, store, source, guard, pose
        self._events = events
        self._publisher = None
        self._published = None  # (map version, zones, held) of the mask on the topic
        self.held = frozenset()
        self.publishes = 0
        self._closed = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="keepout-mask", daemon=True)
        node.when_ready(self._thread.start)

    def _loop(self):
        while not self._closed.wait(PERIOD):
            try:
                self.update()
            except Exception:  # a bad moment (a map cut short) must not end the mask for good
                log.exception("keepout mask: could not publish")

    def update(self):
        """Publish the mask if what it shows changed (also called by tests)."""
        raw = self._source.raw()
        context = self._source.context
        if raw is None or context.get("mode") not in MODES:
            self._withdraw()
            return
        version, message = raw
        zones = tuple(self._store.zones())
        # the pose only matters with a zone on: a map without any costs the loop a file stat
        held = self._guard.holding(self._pose()) if any(z.enabled for z in zones) else frozenset()
        if held != self.held:
            self._tell_held(held)
        key = (version, zones, held)
        if key == self._published:
            return
        grid = self._source.current()[1]
        cells = mask.cells(zones, grid.width, grid.height, grid.resolution, grid.origin_x, grid.origin_y,
                           grid.origin_yaw, skip=held)
        if self._publisher is None:
            self._publisher = own_topics.publisher(self.topic, OccupancyGrid, queue_size=1, latch=True)
        self._publisher.publish(Serialized(serialized_mask(message, cells)))
        self._published = key
        self.publishes += 1
        log.info("keepout mask on %s: %d zone(s) kept out%s", rospy.resolve_name(self.topic),
                 sum(1 for z in zones if z.enabled and z.name not in held),
                 ", {} waiting for the robot to leave".format(len(held)) if held else "")

    def _tell_held(self, held):
        for name in sorted(held - self.held):
            log.warning("zone %r: the robot stands in it; it is kept out again once the robot has left", name)
        self.held = held
        if self._events is not None:
            self._events.publish("zone", {"name": None, "zone": None, "waiting": sorted(held)})

    def _withdraw(self):
        if self._publisher is not None:
            self._publisher.unregister()
            self._publisher = None
            log.info("keepout mask: withdrawn (no map in navigation)")
        self._published = None

    def close(self):
        """Stop publishing. Idempotent."""
        self._closed.set()
        if self._thread.is_alive():
            self._thread.join(2.0)
        self._withdraw()


def serialized_mask(map_message, cells):
    """The bytes of an OccupancyGrid: ``map_message``'s header and info, then ``cells`` as its data."""
    (frame_len,) = struct.unpack_from("<I", map_message, 12)
    head = 16 + frame_len + INFO_BYTES
    return bytes(map_message[:head]) + struct.pack("<I", len(cells)) + cells


class Serialized(OccupancyGrid):
    """An OccupancyGrid already serialized: rospy writes these bytes as they are."""

    __slots__ = ("_bytes",)

    def __init__(self, data):
        super().__init__()
        self._bytes = data

    def serialize(self, buff):
        buff.write(self._bytes)
