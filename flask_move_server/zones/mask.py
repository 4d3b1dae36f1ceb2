"""The keepout mask: a map's enabled zones as the cells of an occupancy grid the costmaps read.

:func:`cells` gives ``width * height`` bytes in the map's own layout (row 0 at the bottom, as
``nav_msgs/OccupancyGrid``): ``LETHAL`` (100) in a cell whose centre lies inside an enabled
keepout polygon or within a wall's half thickness of its line, ``NO_OPINION`` (-1, unknown)
elsewhere. Not free (0): a non-rolling costmap's ``StaticLayer`` with ``use_maximum`` writes a free
cell over an unknown one of the map (costmap_layer.cpp ``updateWithMax``), so a mask of zeros would
open the space the saved map never saw to navfn; an unknown cell it skips. The global costmap's
keepout layer reads -1 as unknown (``track_unknown_space: true``), the rolling local costmap's as
free (``track_unknown_space: false``: there the layer's unknown would win the max in every cell and
DWA could not move): ``zones/costmap_rules.py`` checks both. A wall is drawn at least 0.75 cell
either side of its line, so no path between two diagonal cells slips through it.

Polygons are filled by scanlines (each row's crossings, sorted, filled pairwise with one slice
assignment), walls as one such polygon per segment (a rectangle the thickness wide, reaching half
the thickness past each end), so the cost is the zones' cells, not the map's: a 4000 x 4000 map
costs its 16 MB and little more. Pure: no numpy (which would cost the server ~14 MB
of memory at rest), no rospy.
"""

import math

from flask_move_server.zones import WALL_THICKNESS

LETHAL = 100
NO_OPINION = 0xFF  # -1 as the int8 it is on the wire
WALL_CELLS = 0.75  # a wall's half width is at least this many cells


def cells(zones, width, height, resolution, origin_x, origin_y, origin_yaw=0.0, skip=()):
    """The mask (bytes) of the enabled ``zones`` on a grid of that size, resolution and origin.

    ``skip``: names of zones left out (the robot stands in them: ``keepout.py``)."""
    mask = bytearray(b"\xff") * (width * height)
    to_grid = _to_grid(resolution, origin_x, origin_y, origin_yaw)
    for zone in zones:
        if not zone.enabled or zone.name in skip:
            continue
        for polygon in shapes(zone, resolution):
            _fill(mask, width, height, [to_grid(x, y) for x, y in polygon])
    return bytes(mask)


def shapes(zone, resolution):
    """The polygons (lists of (x, y) in the map frame) that ``zone`` covers."""
    if zone.kind == "keepout":
        return [list(zone.points)]
    half = max(WALL_THICKNESS / 2, WALL_CELLS * resolution)
    return [_band(a, b, half) for a, b in zip(zone.points, zone.points[1:])]


def _band(a, b, half):
    """The rectangle ``half`` either side of segment a-b, reaching ``half`` past both ends."""
    length = math.dist(a, b)
    ux, uy = (b[0] - a[0]) / length, (b[1] - a[1]) / length
    nx, ny = -uy * half, ux * half
    ax, ay = a[0] - ux * half, a[1] - uy * half
    bx, by = b[0] + ux * half, b[1] + uy * half
    return [(ax + nx, ay + ny), (bx + nx, by + ny), (bx - nx, by - ny), (ax - nx, ay - ny)]


def _to_grid(resolution, origin_x, origin_y, origin_yaw):
    """Map-frame (x, y) to grid coordinates in cells (a cell's centre at col + 0.5, row + 0.5)."""
    cos, sin = math.cos(-origin_yaw), math.sin(-origin_yaw)

    def convert(x, y):
        dx, dy = x - origin_x, y - origin_y
        return (dx * cos - dy * sin) / resolution, (dx * sin + dy * cos) / resolution
    return convert


def _fill(mask, width, height, polygon):
    """Set LETHAL in every cell of ``mask`` whose centre lies inside ``polygon`` (grid coordinates), even-odd."""
    ys = [p[1] for p in polygon]
    first = max(0, int(math.floor(min(ys) - 0.5)))
    last = min(height - 1, int(math.ceil(max(ys) - 0.5)))
    edges = list(zip(polygon, polygon[1:] + polygon[:1]))
    lethal = bytes([LETHAL])
    for row in range(first, last + 1):
        y = row + 0.5
        crossings = sorted(x1 + (y - y1) * (x2 - x1) / (y2 - y1)
                           for (x1, y1), (x2, y2) in edges if (y1 > y) != (y2 > y))
        for left, right in zip(crossings[::2], crossings[1::2]):
            start = max(0, int(math.ceil(left - 0.5)))  # the first centre at or right of the crossing
            end = min(width, int(math.ceil(right - 0.5)))  # centres strictly left of the right crossing
            if end > start:
                mask[row * width + start:row * width + end] = lethal * (end - start)
