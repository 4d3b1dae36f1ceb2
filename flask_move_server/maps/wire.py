"""A ``nav_msgs/OccupancyGrid`` decoded straight from its ROS wire bytes into a :class:`Grid`.

genpy's ``OccupancyGrid.deserialize`` turns the cells into a tuple of Python
ints: ~360 ms for gmapping's 4000 x 4000 canvas, for every message. The cells
are already the int8 bytes a :class:`~flask_move_server.maps.mapfile.Grid`
holds, so this reads the fixed fields with ``struct`` and slices the cells out
of the buffer (one copy, a few ms). Only a map someone asks for is decoded.

The layout (ROS serialization: little-endian, strings and arrays prefixed by a
uint32 length)::

    Header header        uint32 seq, time stamp (2 x uint32), string frame_id
    MapMetaData info     time map_load_time, float32 resolution, uint32 width, uint32 height,
                         Pose origin (Point: 3 x float64, Quaternion: 4 x float64)
    int8[] data

Pure: no rospy.
"""

import struct
from dataclasses import dataclass

from flask_move_server.core.geometry import quaternion_to_yaw
from flask_move_server.maps.mapfile import Grid

_UINT32 = struct.Struct("<I")
_INFO = struct.Struct("<2IfII7d")  # map_load_time, resolution, width, height, origin


class BadMapMessage(ValueError):
    """The bytes are not a whole OccupancyGrid (cut short, or sizes that do not agree)."""


@dataclass(frozen=True)
class MapHeader:
    """The message's header fields: sequence number, stamp (s) and frame."""

    seq: int
    stamp: float
    frame_id: str


def shortest_float32(value):
    """The shortest decimal that is the same float32: the 0.05 someone wrote, not 0.05000000074505806."""
    packed = struct.pack("<f", value)
    for digits in range(1, 10):
        candidate = float("{:.{}g}".format(value, digits))
        if struct.pack("<f", candidate) == packed:
            return candidate
    return value


def decode(buff):
    """``(MapHeader, Grid)`` of an OccupancyGrid's serialized bytes; BadMapMessage if they are broken."""
    view = memoryview(buff)
    try:
        seq, secs, nsecs = struct.unpack_from("<3I", view, 0)
        (frame_len,) = _UINT32.unpack_from(view, 12)
        pos = 16 + frame_len
        frame_id = bytes(view[16:pos]).decode("utf-8", "replace")
        _, _, resolution, width, height, x, y, _z, qx, qy, qz, qw = _INFO.unpack_from(view, pos)
        pos += _INFO.size
        (count,) = _UINT32.unpack_from(view, pos)
    except struct.error as exc:
        raise BadMapMessage("the map message is cut short: {}".format(exc)) from None
    pos += 4
    if count != width * height or len(view) < pos + count:
        raise BadMapMessage("the map message says {} x {} cells but carries {} of {} bytes".format(
            width, height, min(count, len(view) - pos), count))
    try:
        grid = Grid(width, height, shortest_float32(resolution), x, y, bytes(view[pos:pos + count]),
                    origin_yaw=quaternion_to_yaw(qx, qy, qz, qw))
    except ValueError as exc:
        raise BadMapMessage("the map message is not a usable grid: {}".format(exc)) from None
    return MapHeader(seq, secs + nsecs * 1e-9, frame_id), grid
