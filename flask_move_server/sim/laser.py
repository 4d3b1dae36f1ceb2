"""A simulated 2D laser scanner (an RPLIDAR A1: 360 beams, 0.15–8 m) by ray casting on the map.

Each beam walks the grid cell by cell (Amanatides–Woo traversal), so a scan
costs one step per cell crossed, and stops at the first occupied cell. The same
walk tells the simulated SLAM (``slam.py``) which cells each beam crossed. Unknown
cells let the beam through; a beam that leaves the map or passes ``range_max``
returns ``inf`` (no echo), as the rplidar driver reports. Pure: no rospy.
"""

import math


class Laser:
    """Casts scans on one occupancy map."""

    def __init__(self, grid, beams=360, range_min=0.15, range_max=8.0):
        self.grid = grid
        self.beams = beams
        self.range_min = range_min
        self.range_max = range_max
        self.angle_min = -math.pi
        self.angle_increment = 2.0 * math.pi / beams
        self._occupied = bytearray(1 if v >= 50 else 0 for v in grid.cells)
        self._directions = [(math.cos(self.angle_min + i * self.angle_increment),
                             math.sin(self.angle_min + i * self.angle_increment)) for i in range(beams)]

    def scan(self, pose):
        """Ranges (m, ``inf`` for no echo) of every beam from ``pose``, beam 0 pointing backwards (-pi)."""
        res = self.grid.resolution
        ranges = []
        for t, _ in self._beams(pose, None):
            r = t * res
            ranges.append(r if self.range_min <= r <= self.range_max else math.inf)
        return ranges

    def trace(self, pose, crossed):
        """Cast a scan from ``pose`` for a mapper: ``crossed(index)`` hears every cell a beam passes
        through before its echo (index into ``grid.cells``, repeats possible); returns, per beam,
        (range in m, index of the echoing cell), or (inf, None) without an echo within ``range_max``.
        """
        res = self.grid.resolution
        return [(t * res, hit) for t, hit in self._beams(pose, crossed)]

    def _beams(self, pose, crossed):
        g = self.grid
        x = (pose.x - g.origin_x) / g.resolution
        y = (pose.y - g.origin_y) / g.resolution
        max_cells = self.range_max / g.resolution
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        for bx, by in self._directions:
            yield self._cast(x, y, c * bx - s * by, s * bx + c * by, max_cells, crossed)

    def _cast(self, x, y, dx, dy, max_cells, crossed=None):
        """(distance in cells, cell index) along (dx, dy) from (x, y) to the first occupied cell;
        (inf, None) when none within ``max_cells``. ``crossed``, when given, hears each cell passed."""
        width, height, occupied = self.grid.width, self.grid.height, self._occupied
        col, row = int(math.floor(x)), int(math.floor(y))
        if not (0 <= col < width and 0 <= row < height):
            return math.inf, None
        p = row * width + col
        if occupied[p]:
            return 0.0, p
        step_c, t_max_c, t_delta_c = _axis(x, col, dx)
        step_r, t_max_r, t_delta_r = _axis(y, row, dy)
        while True:
            if crossed is not None:
                crossed(p)
            if t_max_c < t_max_r:
                t, col, t_max_c = t_max_c, col + step_c, t_max_c + t_delta_c
            else:
                t, row, t_max_r = t_max_r, row + step_r, t_max_r + t_delta_r
            if t > max_cells or not (0 <= col < width and 0 <= row < height):
                return math.inf, None
            p = row * width + col
            if occupied[p]:
                return t, p


def _axis(position, cell, direction):
    """(step, distance to the first cell border, distance between borders) along one axis."""
    if direction > 1e-12:
        return 1, (cell + 1 - position) / direction, 1.0 / direction
    if direction < -1e-12:
        return -1, (position - cell) / -direction, -1.0 / direction
    return 0, math.inf, math.inf
