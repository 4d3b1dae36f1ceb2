"""Does the laser agree with the map where localization says the robot is? Pure (numpy, loaded when used).

AMCL's covariance is the filter's belief, not evidence: an owner set the pose by eye a few degrees
off, the laser's dots visibly missed the walls, and the doctor said "±0.05 m: OK" (issue 33). The
evidence is the scan itself: :func:`match_share` puts each laser end point where the localized
pose says it lies on the map and counts the share that lands on a wall, within one cell of an
occupied one. Furniture, people and open doors the map does not have lower it on a real robot;
a pose 0.3 m or 10° off lowers it far more (tests/test_scan_match.py).
"""

import math

OCCUPIED = 65  # map_server's occupied_thresh 0.65: a cell at or above it is a wall
NEAR_CELLS = 1  # an end point within this many cells of a wall cell counts as on it
MIN_POINTS = 20  # fewer usable end points than this tell nothing


def match_share(grid, pose, laser, scan):
    """``(share, points)``: the share (0-1) of ``scan``'s end points on a wall of ``grid`` with the robot at
    ``pose`` (Pose2D, map frame) and the laser at ``laser`` (Pose2D in base_link); share None when
    fewer than MIN_POINTS end points were usable (in range, on the map)."""
    import numpy as np

    ranges = np.asarray(scan.ranges, dtype=float)
    angles = scan.angle_min + scan.angle_increment * np.arange(len(ranges))
    usable = np.isfinite(ranges) & (ranges > scan.range_min) & (ranges < scan.range_max)
    ranges, angles = ranges[usable], angles[usable]
    lx, ly = laser.x + ranges * np.cos(laser.yaw + angles), laser.y + ranges * np.sin(laser.yaw + angles)
    return _share(grid, pose, lx, ly)


def points_share(grid, pose, points):
    """As :func:`match_share`, for end points given in the robot's frame (``[(x, y), ...]``, base_link)."""
    import numpy as np

    xy = np.asarray(points, dtype=float).reshape(-1, 2)
    return _share(grid, pose, xy[:, 0], xy[:, 1])


def _share(grid, pose, lx, ly):
    """``(share, points)`` of end points (``lx``, ``ly`` in base_link, numpy arrays) on a wall at ``pose``."""
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    mx, my = pose.x + c * lx - s * ly, pose.y + s * lx + c * ly
    col, row = _cells(grid, mx, my)
    inside = (col >= 0) & (col < grid.width) & (row >= 0) & (row < grid.height)
    if int(inside.sum()) < MIN_POINTS:
        return None, int(inside.sum())
    return float(_near_walls(grid, row[inside], col[inside]).mean()), int(inside.sum())


def _cells(grid, mx, my):
    import numpy as np

    dx, dy = mx - grid.origin_x, my - grid.origin_y
    c, s = math.cos(grid.origin_yaw), math.sin(grid.origin_yaw)
    gx, gy = c * dx + s * dy, -s * dx + c * dy
    return np.floor(gx / grid.resolution).astype(int), np.floor(gy / grid.resolution).astype(int)


def _near_walls(grid, row, col):
    """For each cell (``row``, ``col``, rows bottom first): a wall there or within NEAR_CELLS of it.
    Only the cells around the end points are read, never the whole map (a gmapping map is 4000²)."""
    import numpy as np

    cells = np.frombuffer(grid.cells, dtype=np.int8).reshape(grid.height, grid.width)
    near = np.zeros(len(row), dtype=bool)
    for dr in range(-NEAR_CELLS, NEAR_CELLS + 1):
        for dc in range(-NEAR_CELLS, NEAR_CELLS + 1):
            r, c = row + dr, col + dc
            on_map = (r >= 0) & (r < grid.height) & (c >= 0) & (c < grid.width)
            near[on_map] |= cells[r[on_map], c[on_map]] >= OCCUPIED
    return near
