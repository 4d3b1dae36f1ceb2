"""The robot's footprint against what the laser and the map say: touching, and the room behind. Pure.

The footprint is the one move_base's costmaps use (``costmap_common.yaml``: ``footprint`` and
``footprint_padding``, or ``robot_radius``), padded as costmap_2d pads it (``padFootprint``: each
corner moved ``padding`` outward in x and in y). move_base cannot plan nor rotate from a pose
whose footprint holds a lethal cell, and navfn plans through no cell within the inscribed radius
of one: :func:`on_the_map` is that look at the localized pose. :func:`touching` asks the laser the
same about the real world, :func:`room_along` how far the robot may back out (or pull out forwards).
"""

import math
import os

import yaml

OCCUPIED = 65  # map_server's occupied_thresh 0.65, as costmap_2d's static layer reads a saved map
DEFAULT = [[0.15, 0.15], [0.15, -0.15], [-0.15, -0.15], [-0.15, 0.15]]


def read_polygon(folder):
    """The footprint polygon in ``folder``'s costmap_common.yaml (unpadded), or an octagon of its
    ``robot_radius``; None when the file has neither (or cannot be read)."""
    params = _common(folder)
    footprint = params.get("footprint")
    if isinstance(footprint, list) and len(footprint) >= 3 and all(_point(p) for p in footprint):
        return [[float(p[0]), float(p[1])] for p in footprint]
    radius = params.get("robot_radius")
    if isinstance(radius, (int, float)) and radius > 0:
        return [[radius * math.cos(a), radius * math.sin(a)] for a in (k * math.pi / 4 for k in range(8))]
    return None


def read(folder):
    """The footprint move_base uses, padded (``footprint_padding``): a list of (x, y); DEFAULT padded by
    nothing when the file says nothing usable."""
    polygon = read_polygon(folder) or DEFAULT
    padding = _common(folder).get("footprint_padding", 0.01)
    padding = float(padding) if isinstance(padding, (int, float)) and math.isfinite(padding) else 0.0
    return padded(polygon, padding)


def padded(polygon, padding):
    """costmap_2d's padFootprint: each point ``padding`` further out in x and in y (by its sign)."""
    return [(x + math.copysign(padding, x) if x else x, y + math.copysign(padding, y) if y else y)
            for x, y in polygon]


def inscribed_radius(polygon):
    """The distance from the centre to the nearest edge (costmap_2d's calculateMinAndMaxDistances)."""
    return min(_distance_to_segment(0.0, 0.0, a, b) for a, b in _edges(polygon))


def circumscribed_radius(polygon):
    return max(math.hypot(x, y) for x, y in polygon)


def contains(polygon, x, y, margin=0.0):
    """True when (x, y) lies inside ``polygon`` or within ``margin`` of its outline."""
    if margin > 0 and any(_distance_to_segment(x, y, a, b) <= margin for a, b in _edges(polygon)):
        return True
    inside = False
    for (x0, y0), (x1, y1) in _edges(polygon):
        if (y0 > y) != (y1 > y) and x < x0 + (y - y0) * (x1 - x0) / (y1 - y0):
            inside = not inside
    return inside


def touching(points, polygon, margin):
    """The laser's end points (robot frame) inside the footprint or within ``margin`` of it."""
    reach = circumscribed_radius(polygon) + margin
    return [(x, y) for x, y in points if math.hypot(x, y) <= reach and contains(polygon, x, y, margin)]


def room_along(points, polygon, reach, margin, way=-1):
    """How far (m, at most ``reach``) the robot may drive straight back (``way`` -1; +1: ahead) before its
    footprint would come within ``margin`` of an end point in the lane it sweeps. A wall alongside,
    outside the (padded) footprint's width, is not in the way: backing out keeps its distance."""
    xs = [x for x, _ in polygon]
    edge = min(xs) if way < 0 else max(xs)
    half_width = max(abs(y) for _, y in polygon)
    room = reach
    for x, y in points:
        beyond = (edge - x) if way < 0 else (x - edge)  # how far beyond the footprint's edge
        if abs(y) <= half_width and beyond >= -margin:  # in the lane the back-out sweeps (not alongside)
            room = min(room, max(0.0, beyond - margin))
    return room


def on_the_map(grid, pose, polygon):
    """True when the footprint at ``pose`` (Pose2D, map frame) holds an occupied cell of ``grid``, or its
    centre lies within the inscribed radius of one: where move_base can neither plan nor turn."""
    reach = circumscribed_radius(polygon)
    inscribed = inscribed_radius(polygon)
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    res = grid.resolution
    col0, row0 = _cell(grid, pose.x, pose.y)
    span = int(math.ceil(reach / res)) + 1
    for row in range(max(0, row0 - span), min(grid.height, row0 + span + 1)):
        for col in range(max(0, col0 - span), min(grid.width, col0 + span + 1)):
            if _value(grid, col, row) < OCCUPIED:
                continue
            mx, my = _centre(grid, col, row)
            dx, dy = mx - pose.x, my - pose.y
            lx, ly = c * dx + s * dy, -s * dx + c * dy  # the cell in the robot's frame
            if math.hypot(lx, ly) <= inscribed or contains(polygon, lx, ly, res / 2.0):
                return True
    return False


def _cell(grid, x, y):
    dx, dy = x - grid.origin_x, y - grid.origin_y
    c, s = math.cos(grid.origin_yaw), math.sin(grid.origin_yaw)
    return int(math.floor((c * dx + s * dy) / grid.resolution)), int(math.floor((-s * dx + c * dy) / grid.resolution))


def _centre(grid, col, row):
    gx, gy = (col + 0.5) * grid.resolution, (row + 0.5) * grid.resolution
    c, s = math.cos(grid.origin_yaw), math.sin(grid.origin_yaw)
    return grid.origin_x + c * gx - s * gy, grid.origin_y + s * gx + c * gy


def _value(grid, col, row):
    byte = grid.cells[row * grid.width + col]
    return byte - 256 if byte > 127 else byte


def _edges(polygon):
    return list(zip(polygon, list(polygon[1:]) + [polygon[0]]))


def _distance_to_segment(x, y, a, b):
    (ax, ay), (bx, by) = a, b
    dx, dy = bx - ax, by - ay
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0 else max(0.0, min(1.0, ((x - ax) * dx + (y - ay) * dy) / length2))
    return math.hypot(x - ax - t * dx, y - ay - t * dy)


def _common(folder):
    try:
        with open(os.path.join(folder, "costmap_common.yaml"), encoding="utf-8") as f:
            params = yaml.safe_load(f)
    except (OSError, yaml.YAMLError):
        return {}
    return params if isinstance(params, dict) else {}


def _point(p):
    return isinstance(p, list) and len(p) == 2 and all(isinstance(v, (int, float)) for v in p)
