"""Simulated SLAM: the occupancy grid gmapping would publish, grown from scans of the true world.

The robot starts knowing nothing: every cell of the canvas is unknown (-1).
Each scan is cast on the TRUE world by the simulated laser (``Laser.trace``,
the same grid traversal as ``/scan``) from the robot's true pose; the cells a
beam crosses gain evidence of being free, the cell it echoes from evidence of
being occupied (log-odds, clamped so a cell can still change its mind). A beam
without an echo within ``range_max`` marks free only (up to ``range_max`` or the
true map's edge); an echo closer than ``range_min`` marks no obstacle, as the
real laser reports none there. Beams stop at the first wall, so nothing is
ever marked through one. A cell is published as gmapping does: unknown
until a beam touched it, then occupied (100) when its probability exceeds
``occ_thresh`` (gmapping's 0.25), else free (0).

The published grid is a ``bytearray`` of signed bytes, bottom row first like
``nav_msgs/OccupancyGrid.data``, updated in place for the cells a scan touched
only, so handing it out costs one copy, never per-cell Python work over a
canvas that may be 4000 x 4000. ``version`` counts the scans that changed it.

``GrowingMapPlanner`` plans on it as move_base does with ``allow_unknown``:
unknown cells are traversable, cells seen occupied are obstacles.

Pure: no rospy.
"""

import math
from array import array
from dataclasses import dataclass

from flask_move_server.sim.costmap import Costmap
from flask_move_server.sim.occupancy import OccupancyMap
from flask_move_server.sim.planner import Planner

UNKNOWN_BYTE, FREE_BYTE, OCCUPIED_BYTE = 0xFF, 0, 100  # -1, 0, 100 as signed bytes
SCALE = 20.0  # stored log-odds units per unit of log-odds (an int8 holds about -6.4 .. 6.35)


def _log_odds(p):
    return int(round(SCALE * math.log(p / (1.0 - p))))


@dataclass(frozen=True)
class SensorModel:
    """How much one beam says about a cell, and where a cell turns occupied.

    The prior (0.2) sits below ``occ_thresh`` (0.25), so, as with gmapping's
    hit ratio, a cell's first observation decides it: one echo makes it
    occupied, one pass-through free; later ones move it by log-odds steps.
    """

    hit: float = 0.7
    miss: float = 0.4
    prior: float = 0.2
    clamp_low: float = 0.12
    clamp_high: float = 0.97
    occ_thresh: float = 0.25

    def units(self):
        """(hit, miss, prior, low, high, occupied-above) in stored log-odds units."""
        return (_log_odds(self.hit), _log_odds(self.miss), _log_odds(self.prior), _log_odds(self.clamp_low),
                _log_odds(self.clamp_high), math.floor(SCALE * math.log(self.occ_thresh / (1.0 - self.occ_thresh))))


class SlamMap:
    """The growing map: a canvas of ``width`` x ``height`` cells at the true map's resolution."""

    def __init__(self, laser, width, height, origin_x, origin_y, model=SensorModel()):
        truth = laser.grid
        self.laser = laser
        self.resolution = truth.resolution
        self.width, self.height = width, height
        self.origin_x, self.origin_y = origin_x, origin_y
        self._shift = (_whole_cells(truth.origin_x - origin_x, truth.resolution),
                       _whole_cells(truth.origin_y - origin_y, truth.resolution))
        self._truth_width = truth.width
        self._hit, self._miss, prior, self._low, self._high, self._occupied_above = model.units()
        self._log_odds = array("b", [prior]) * (width * height)
        self._published = bytearray([UNKNOWN_BYTE]) * (width * height)
        self.version = 0
        self.scans = 0

    @classmethod
    def around(cls, laser, margin=2.0, model=SensorModel()):
        """A canvas covering the true map plus ``margin`` metres on every side."""
        truth = laser.grid
        pad = int(math.ceil(margin / truth.resolution))
        return cls(laser, truth.width + 2 * pad, truth.height + 2 * pad,
                   truth.origin_x - pad * truth.resolution, truth.origin_y - pad * truth.resolution, model)

    def integrate(self, pose):
        """Add one scan from the true ``pose``; returns how many published cells changed."""
        crossed = set()
        beams = self.laser.trace(pose, crossed.add)
        range_min = self.laser.range_min
        hits = {p for r, p in beams if p is not None and r >= range_min}
        changed = self._update(crossed, self._miss) + self._update(hits, self._hit)
        self.scans += 1
        if changed:
            self.version += 1
        return changed

    def _update(self, truth_cells, step):
        """Move the log-odds of each true-map cell by ``step``; returns how many published values changed."""
        log_odds, published = self._log_odds, self._published
        low, high, above = self._low, self._high, self._occupied_above
        width, truth_width = self.width, self._truth_width
        shift_c, shift_r = self._shift
        changed = 0
        for p in truth_cells:
            row, col = divmod(p, truth_width)
            row, col = row + shift_r, col + shift_c
            if not (0 <= row < self.height and 0 <= col < width):
                continue
            q = row * width + col
            value = log_odds[q] + step
            value = low if value < low else high if value > high else value
            log_odds[q] = value
            shown = OCCUPIED_BYTE if value > above else FREE_BYTE
            if published[q] != shown:
                published[q] = shown
                changed += 1
        return changed

    def grid_bytes(self):
        """The grid as ``nav_msgs/OccupancyGrid.data`` holds it: signed bytes -1 / 0 / 100, bottom row first."""
        return bytes(self._published)

    def value_at(self, x, y):
        """-1 unknown, 0 free, 100 occupied at map point (x, y); None off the canvas."""
        col = int(math.floor((x - self.origin_x) / self.resolution))
        row = int(math.floor((y - self.origin_y) / self.resolution))
        if not (0 <= col < self.width and 0 <= row < self.height):
            return None
        value = self._published[row * self.width + col]
        return value - 256 if value > 127 else value

    def occupancy_map(self, source="(simulated SLAM)"):
        """A snapshot as an :class:`OccupancyMap` (per-cell work: for saving a map, not for every update)."""
        cells = list(array("b", bytes(self._published)))
        return OccupancyMap(self.width, self.height, self.resolution, self.origin_x, self.origin_y, cells, source)


def _whole_cells(metres, resolution):
    cells = metres / resolution
    if abs(cells - round(cells)) > 1e-6:
        raise ValueError("the SLAM canvas must be offset from the true map by whole cells, got {} m".format(metres))
    return int(round(cells))


class _KnownObstacles(OccupancyMap):
    """The SLAM grid as the costmap reads it: only cells seen occupied block (move_base's ``allow_unknown``).

    ``cells`` holds the published bytes as they are (unknown is 255 here, not -1).
    """

    def blocked(self):
        return bytearray(self.cells.translate(_BLOCKS))


_BLOCKS = bytes(1 if v == OCCUPIED_BYTE else 0 for v in range(256))


class GrowingMapPlanner:
    """A :class:`Planner` on the SLAM grid, its costmap rebuilt when the map has changed since the last plan.

    Drop-in for the move_base stand-in's planner: ``plan(start, goal)`` and ``check_goal(x, y)``.
    """

    def __init__(self, slam, radius, margin=0.0):
        self.slam = slam
        self.radius, self.margin = radius, margin
        self._planner = None
        self._version = None
        self.rebuilds = 0

    def _current(self):
        version = self.slam.version
        if self._planner is None or version != self._version:
            s = self.slam
            grid = _KnownObstacles(s.width, s.height, s.resolution, s.origin_x, s.origin_y, s.grid_bytes(),
                                   "(simulated SLAM, version {})".format(version))
            self._planner = Planner(Costmap(grid, self.radius, self.margin))
            self._version = version
            self.rebuilds += 1
        return self._planner

    @property
    def costmap(self):
        return self._current().costmap

    def check_goal(self, x, y):
        """Raise PlanningFailed when no robot could stand at (x, y) on what is known now."""
        return self._current().check_goal(x, y)

    def plan(self, start, goal):
        """A path from ``start`` to ``goal`` through free and unknown cells, around the obstacles seen so far."""
        return self._current().plan(start, goal)

    def path_blocked(self, points):
        """True when an obstacle seen since ``points`` was planned lies in the robot's way along it.

        The move_base stand-in can ask this when the map's version changes, and replan (move_base
        replans on its growing costmap too). The first point (where the robot stood) is not checked:
        a robot close to a wall may stand in an inflated cell.
        """
        costmap = self._current().costmap
        step = costmap.resolution / 2.0
        for (ax, ay), (bx, by) in zip(points, points[1:]):
            n = max(1, int(math.ceil(math.hypot(bx - ax, by - ay) / step)))
            for k in range(1, n + 1):
                if costmap.lethal_at(ax + (bx - ax) * k / n, ay + (by - ay) * k / n):
                    return True
        return False
