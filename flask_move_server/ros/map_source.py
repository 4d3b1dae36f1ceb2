"""The map in use now, as the navigation stack publishes it on ``/map`` (``maps.topic``).

Subscribed with ``rospy.AnyMsg``: rospy hands over the serialized bytes and
nothing else, so a 4000 x 4000 gmapping map costs a byte copy per message,
not genpy's ~360 ms tuple of 16 M ints. The bytes are decoded
(:mod:`flask_move_server.maps.wire`) only when someone asks for the map, once
per version. ``version`` counts the maps received since start (never reset,
so an image's ETag never names two different maps in one run).

Every new map publishes a ``map`` event ``{"version", "mode", "map"}`` (at
most one per ``event_period``, the last one always sent). The map is
forgotten when the mode's stack stops (a ``mode`` event in state
``stopping``, or mode ``idle``): the next stack's latched map replaces it, and
meanwhile ``GET /map`` says no map is published rather than show the old one.
"""

import io
import logging
import threading
import time

import rospy

from flask_move_server.core.errors import MapNotReceived, NoMap
from flask_move_server.maps.wire import BadMapMessage, decode

log = logging.getLogger(__name__)

MAP_TYPE = "nav_msgs/OccupancyGrid"
RECV_CHUNK = 1 << 22  # rospy reads a message in recv() calls of this size: 4 calls for a 16 MB map


class MapSource:
    """The latest map message of one topic: raw bytes, a version, and the grid decoded on demand."""

    def __init__(self, node, topic="map", events=None, event_period=1.0):
        self.topic = topic
        self._events = events
        self._event_period = event_period
        self._cond = threading.Condition()
        self._raw = None
        self._version = 0
        self._context = {"mode": None, "map": None}
        self._decoded = (None, None)  # (version, Grid)
        self._decode_lock = threading.Lock()
        self._announced_at = float("-inf")
        self._timer = None
        self._closed = False
        self._sub = None
        self._wrong_type = None
        self.mode_of = None  # a callable giving {"mode", "map"} now (the mode manager's), else the last event's
        if events is not None:
            events.listen("mode", self._on_mode)
        node.when_ready(self._setup)

    def _setup(self):
        if self._closed:
            return
        self._sub = rospy.Subscriber(self.topic, rospy.AnyMsg, self._on_map, queue_size=1, buff_size=RECV_CHUNK)
        log.info("following the map on %s", rospy.resolve_name(self.topic))

    # arriving maps -------------------------------------------------------------------------

    def _on_map(self, msg):
        kind = (getattr(msg, "_connection_header", None) or {}).get("type", MAP_TYPE)
        if kind != MAP_TYPE:
            if kind != self._wrong_type:
                log.warning("ignoring %s on %s: a map is a %s", kind, self.topic, MAP_TYPE)
                self._wrong_type = kind
            return
        raw = _raw_bytes(msg)
        with self._cond:
            if self._closed:
                return
            self._raw = raw
            self._version += 1
            self._cond.notify_all()
        self._announce()

    def _on_mode(self, status):
        """A ``mode`` event: remember the mode for the map events; forget the map when its stack stops."""
        with self._cond:
            self._context = {"mode": status.get("mode"), "map": status.get("map")}
            if status.get("state") == "stopping" or status.get("mode") == "idle":
                self._raw = None

    def _announce(self):
        """Publish a ``map`` event now, or once ``event_period`` has passed since the last one."""
        if self._events is None:
            return
        with self._cond:
            wait = self._announced_at + self._event_period - time.monotonic()
            if self._closed or (wait > 0 and self._timer is not None):
                return
            if wait > 0:
                self._timer = threading.Timer(wait, self._announce_late)
                self._timer.daemon = True
                self._timer.start()
                return
            self._announced_at = time.monotonic()
            version = self._version
        self._events.publish("map", dict(self.context, version=version))

    def _announce_late(self):
        with self._cond:
            self._timer = None
        self._announce()

    # reading -------------------------------------------------------------------------------

    @property
    def version(self):
        """How many maps arrived since start (0: none yet)."""
        with self._cond:
            return self._version

    @property
    def context(self):
        """``{"mode", "map"}``: what the map in use belongs to (``mode_of()``, else the last ``mode`` event)."""
        told = self.mode_of() if self.mode_of is not None else None
        if told is not None:
            return told
        with self._cond:
            return dict(self._context)

    def held_version(self):
        """The version of the map held now, without decoding it (an ETag check); NoMap when none is."""
        with self._cond:
            if self._raw is None:
                raise self._no_map()
            return self._version

    def current(self):
        """``(version, Grid)`` of the map held now; NoMap when none is published."""
        with self._cond:
            raw, version = self._raw, self._version
        if raw is None:
            raise self._no_map()
        return version, self._grid(version, raw)

    def raw(self):
        """``(version, serialized bytes)`` of the map held now, None when none is (the mask copies its header)."""
        with self._cond:
            return None if self._raw is None else (self._version, self._raw)

    def _no_map(self):
        return NoMap("No map is published on the topic {} now: the robot is idle, or its mapping or navigation "
                     "is still starting (GET /mode says which).".format(rospy.resolve_name(self.topic)))

    def latest(self, timeout):
        """``(version, Grid)`` of the map held now, waiting up to ``timeout`` s for one; MapNotReceived else."""
        with self._cond:
            self._cond.wait_for(lambda: self._raw is not None or self._closed, timeout)
        try:
            return self.current()
        except NoMap:
            raise MapNotReceived("No map arrived on {} within {:g} s: is mapping running? (GET /mode)".format(
                self.topic, timeout)) from None

    def fresh_after(self, version, timeout):
        """``(version, Grid)`` of the first map newer than ``version``, waiting up to ``timeout`` s."""
        with self._cond:
            self._cond.wait_for(lambda: (self._raw is not None and self._version > version) or self._closed,
                                timeout)
            newer = self._version > version
        if not newer:
            raise MapNotReceived("No new map arrived on {} within {:g} s: is mapping running? (GET /mode)".format(
                self.topic, timeout))
        return self.current()

    def _grid(self, version, raw):
        """The decoded grid of ``version`` (decoded once, whoever asks first)."""
        with self._decode_lock:
            if self._decoded[0] != version:
                try:
                    self._decoded = (version, decode(raw)[1])
                except BadMapMessage as exc:
                    raise NoMap("The map on {} cannot be read: {}.".format(self.topic, exc)) from None
            return self._decoded[1]

    def close(self):
        """Unsubscribe and wake every waiter. Idempotent."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            timer, self._timer = self._timer, None
            self._cond.notify_all()
        if timer is not None:
            timer.cancel()
        if self._sub is not None:
            self._sub.unregister()


def _raw_bytes(msg):
    """The message's serialized bytes. rospy shares one subscription per topic and process, typed by
    the first subscriber: if another part subscribed to the map topic with ``OccupancyGrid`` first,
    a decoded message comes here, and is serialized back (slow, but right)."""
    raw = getattr(msg, "_buff", None)
    if raw is not None:
        return raw
    buff = io.BytesIO()
    msg.serialize(buff)
    return buff.getvalue()
