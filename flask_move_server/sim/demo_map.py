"""The demo flat, drawn from rectangles: ``python -m flask_move_server.sim.demo_map [OUT_DIR]``.

Regenerates ``config/maps/demo.pgm`` and ``demo.yaml`` (map_server format, as
``map_saver`` writes them: 254 free, 0 occupied, 205 unknown). The flat is
12 m × 8 m at 5 cm per cell: a living room with the robot's dock at the map
origin, a kitchen-diner with a locked store room, an office and a bedroom,
joined by 0.9 m doors, with furniture. Where the shipped files are (:func:`default_map`, the
config folder beside them) is here too, for every part that falls back on them: the sim, the
configured map, the launched stack. Pure: no rospy.
"""

import math
import os
import sys

from flask_move_server.sim.occupancy import write_pgm

FREE_PIXEL, WALL_PIXEL, UNKNOWN_PIXEL = 254, 0, 205
RESOLUTION = 0.05
# The image covers x in [-2.5, 10.5], y in [-2.5, 6.5]; the flat's outer walls run at x -2..10, y -2..6.
ORIGIN = (-2.5, -2.5)
SIZE = (13.0, 9.0)

# (x0, y0, x1, y1) in metres, map frame.
FLOOR = (-2.0, -2.0, 10.0, 6.0)
WALLS = [
    # outer walls, 15 cm
    (-2.15, -2.15, 10.15, -2.0), (-2.15, 6.0, 10.15, 6.15), (-2.15, -2.15, -2.0, 6.15), (10.0, -2.15, 10.15, 6.15),
    # living room | office, bedroom: wall at y = 2.5 with doors at x 0.3..1.2 and 5.0..5.9
    (-2.0, 2.45, 0.3, 2.55), (1.2, 2.45, 5.0, 2.55), (5.9, 2.45, 10.0, 2.55),
    # office | bedroom
    (3.45, 2.55, 3.55, 6.0),
    # living room | kitchen: wall at x = 4 with a door at y 0.6..1.5
    (3.95, -2.0, 4.05, 0.6), (3.95, 1.5, 4.05, 2.45),
    # the store room in the kitchen's corner: no door
    (5.2, -2.0, 5.3, -0.95), (4.05, -1.05, 5.3, -0.95),
]
FURNITURE = [
    (-1.9, -0.8, -1.1, 1.6),    # sofa
    (1.0, -1.2, 2.0, -0.6),     # coffee table
    (3.4, -1.5, 3.95, -0.3),    # TV stand
    (9.3, -2.0, 10.0, 1.5),     # kitchen counter
    (6.0, -0.8, 7.5, 0.6),      # dining table
    (5.5, -0.35, 5.8, -0.05), (7.7, -0.35, 8.0, -0.05),  # chairs
    (-1.9, 5.2, 0.0, 6.0),      # desk
    (2.9, 3.5, 3.45, 5.5),      # bookshelf
    (7.5, 3.8, 10.0, 6.0),      # bed
    (3.55, 5.4, 5.0, 6.0),      # wardrobe
]


def demo_pixels():
    """(width, height, pixels top row first) of the demo flat."""
    width, height = int(round(SIZE[0] / RESOLUTION)), int(round(SIZE[1] / RESOLUTION))
    pixels = bytearray([UNKNOWN_PIXEL]) * (width * height)
    _fill(pixels, width, height, FLOOR, FREE_PIXEL)
    for rect in WALLS + FURNITURE:
        _fill(pixels, width, height, rect, WALL_PIXEL)
    return width, height, pixels


def _fill(pixels, width, height, rect, value):
    x0, y0, x1, y1 = rect
    c0, c1 = _cell(x0 - ORIGIN[0]), _cell(x1 - ORIGIN[0])
    r0, r1 = _cell(y0 - ORIGIN[1]), _cell(y1 - ORIGIN[1])
    for row in range(max(0, r0), min(height, r1)):
        top_row = height - 1 - row
        start = top_row * width
        pixels[start + max(0, c0):start + min(width, c1)] = bytes([value]) * (min(width, c1) - max(0, c0))


def _cell(metres):
    return int(math.floor(metres / RESOLUTION + 0.5))


def map_yaml(image_name):
    """The map_server YAML that goes with the image."""
    return (
        "# The demo flat for `flask-move-server --sim`; regenerate with python -m flask_move_server.sim.demo_map\n"
        "image: {}\nresolution: {}\norigin: [{}, {}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n"
        "mode: trinary\n"
    ).format(image_name, RESOLUTION, ORIGIN[0], ORIGIN[1])


def write(out_dir, name="demo"):
    """Write ``<name>.pgm`` and ``<name>.yaml`` into ``out_dir``; returns the YAML path."""
    width, height, pixels = demo_pixels()
    write_pgm(os.path.join(out_dir, name + ".pgm"), width, height, pixels)
    path = os.path.join(out_dir, name + ".yaml")
    with open(path, "w", encoding="utf-8") as f:
        f.write(map_yaml(name + ".pgm"))
    return path


def default_map():
    """The shipped demo map: config/maps/demo.yaml in the checkout (or the installed share dir)."""
    here = os.path.dirname(os.path.abspath(__file__))
    candidates = [
        os.path.join(here, "..", "..", "config", "maps", "demo.yaml"),
        os.path.join(sys.prefix, "share", "flask_move_server", "config", "maps", "demo.yaml"),
    ]
    for path in candidates:
        if os.path.exists(path):
            return os.path.normpath(path)
    return os.path.normpath(candidates[0])


def default_navigation_config():
    """The folder of the shipped move_base.yaml and dwa_local_planner.yaml (the demo map's config/)."""
    return os.path.dirname(os.path.dirname(default_map()))


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    out_dir = argv[0] if argv else os.path.join(root, "config", "maps")
    os.makedirs(out_dir, exist_ok=True)
    print(write(out_dir))
    return 0


if __name__ == "__main__":
    sys.exit(main())
