"""Worlds for the exploration tests, drawn from rectangles like the demo flat (``sim/demo_map.py``).

Each is a map_server map (PGM + YAML) the simulated world is made of; the robot starts at x=0, y=0.
Walls are 0.1 m thick; doors are gaps in them. ``write(folder, name)`` gives the YAML's path.

- ``hall``: one open 9 x 7 m hall with pillars and a sofa (nothing hidden but behind furniture).
- ``rooms``: a corridor with three rooms behind 0.7 m doors, one of them round a corner.
- ``dead_end``: a room, and a 1 m corridor from it that ends in a wall 6 m on (it must be left again).
- ``narrow``: a room with a second room behind a 0.2 m gap (the robot is 0.3 m across): the laser
  sees into it through the gap, but no robot gets there, so it is unreachable, not looped on.
"""

import math
import os

from flask_move_server.sim.occupancy import write_pgm

FREE, WALL, UNKNOWN = 254, 0, 205
RESOLUTION = 0.05
T = 0.1  # wall thickness


def _box(x0, y0, x1, y1):
    """Four walls around the rectangle (inside faces at the given coordinates)."""
    return [(x0 - T, y0 - T, x1 + T, y0), (x0 - T, y1, x1 + T, y1 + T), (x0 - T, y0, x0, y1), (x1, y0, x1 + T, y1)]


WORLDS = {
    "hall": {
        "floor": [(-1.0, -1.0, 8.0, 6.0)],
        "walls": _box(-1.0, -1.0, 8.0, 6.0) + [
            (2.5, 2.0, 2.9, 2.4), (5.5, 2.0, 5.9, 2.4), (2.5, 4.0, 2.9, 4.4),  # pillars
            (6.5, -1.0, 8.0, 0.0),  # a sofa in the corner
        ],
    },
    "rooms": {
        # corridor y 0..1.2 from x -1 to 9; rooms above (y 1.3..5) and one below, round the corner
        "floor": [(-1.0, -0.6, 9.0, 1.2), (-1.0, 1.3, 3.0, 5.0), (3.1, 1.3, 9.0, 5.0), (6.0, -4.5, 9.0, -0.7)],
        "walls": _box(-1.0, -0.6, 9.0, 1.2) + _box(-1.0, 1.3, 3.0, 5.0) + _box(3.1, 1.3, 9.0, 5.0)
        + _box(6.0, -4.5, 9.0, -0.7),
        "doors": [(0.8, 1.2, 1.5, 1.3), (5.0, 1.2, 5.7, 1.3), (7.0, -0.7, 7.7, -0.6)],
    },
    "dead_end": {
        "floor": [(-1.0, -1.0, 3.0, 3.0), (3.1, 0.5, 9.0, 1.5)],
        "walls": _box(-1.0, -1.0, 3.0, 3.0) + _box(3.1, 0.5, 9.0, 1.5),
        "doors": [(3.0, 0.5, 3.1, 1.5)],
    },
    "narrow": {
        "floor": [(-1.0, -1.0, 3.0, 3.0), (3.1, -1.0, 6.0, 3.0)],
        "walls": _box(-1.0, -1.0, 3.0, 3.0) + _box(3.1, -1.0, 6.0, 3.0),
        "doors": [(3.0, 0.9, 3.1, 1.1)],  # 0.2 m: the laser passes, the robot does not
    },
}


def pixels(world):
    """(width, height, origin, pixels top row first) of a world: unknown around, free floors, walls."""
    spec = WORLDS[world]
    rects = spec["floor"] + spec["walls"]
    x0 = min(r[0] for r in rects) - 0.5
    y0 = min(r[1] for r in rects) - 0.5
    x1 = max(r[2] for r in rects) + 0.5
    y1 = max(r[3] for r in rects) + 0.5
    origin = (math.floor(x0), math.floor(y0))
    width = int(round((math.ceil(x1) - origin[0]) / RESOLUTION))
    height = int(round((math.ceil(y1) - origin[1]) / RESOLUTION))
    image = bytearray([UNKNOWN]) * (width * height)
    for rect in spec["floor"]:
        _fill(image, width, height, origin, rect, FREE)
    for rect in spec["walls"]:
        _fill(image, width, height, origin, rect, WALL)
    for rect in spec.get("doors", ()):
        _fill(image, width, height, origin, rect, FREE)
    return width, height, origin, image


def _fill(image, width, height, origin, rect, value):
    x0, y0, x1, y1 = rect
    c0, c1 = _cell(x0 - origin[0]), _cell(x1 - origin[0])
    r0, r1 = _cell(y0 - origin[1]), _cell(y1 - origin[1])
    for row in range(max(0, r0), min(height, r1)):
        start = (height - 1 - row) * width
        lo, hi = max(0, c0), min(width, c1)
        image[start + lo:start + hi] = bytes([value]) * (hi - lo)


def _cell(metres):
    return int(math.floor(metres / RESOLUTION + 0.5))


def write(folder, world):
    """``<world>.pgm`` and ``<world>.yaml`` in ``folder``; the YAML's path."""
    width, height, origin, image = pixels(world)
    write_pgm(os.path.join(str(folder), world + ".pgm"), width, height, image)
    path = os.path.join(str(folder), world + ".yaml")
    with open(path, "w", encoding="utf-8") as f:
        f.write("image: {}.pgm\nresolution: {}\norigin: [{}, {}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n"
                "free_thresh: 0.196\nmode: trinary\n".format(world, RESOLUTION, float(origin[0]), float(origin[1])))
    return path
