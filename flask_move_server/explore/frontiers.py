"""Frontiers of a growing map, and where the robot can reach: the explorer's pure core (issue 24).

A *frontier cell* is a known free cell with an unknown 4-neighbour: from near it the laser sees new
space. Frontier cells that touch (8-connected) form a *group*, and the explorer drives to one group
at a time. explore_lite (m-explore) sends the robot to a group's centroid or its nearest cell, which
may lie in a wall's inflation or behind a gap the robot cannot pass; here a group's *target* is a
cell the robot can stand on (its centre more than ``radius`` from every occupied cell, as
``sim/costmap.py`` inflates: lethal when the distance between cell centres is at most
``radius / resolution + 0.5`` cells) and reach (4-connected to the robot's cell through such cells).
Unknown space is no obstacle to move_base (``allow_unknown``), but reachability walks known free
cells only, so a target is never a guess. A group no reachable cell serves is reported apart.

Cell values as ``nav_msgs/OccupancyGrid`` has them: negative unknown, 0..49 free, 50 and up occupied.

Speed: a gmapping canvas is 4000 x 4000 cells (16 MB), of which a flat covers a few hundred
thousand, so everything runs on the bounding box of the known cells plus one cell all round (found
by one numpy reduction), and every step is a whole-array numpy operation: the inflation is a disk
dilation made separable (one row dilation per half-width of the disk, then one vertical shift per
row of it), and connected components are found by :func:`label` over runs of cells, without scipy
(heavy, and not on every Pi). numpy is python3-numpy in Debian, Raspberry Pi OS and Ubuntu 20.04
(1.17, which is what this module may use). Pure: no rospy, no Flask.
"""

import dataclasses
import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from flask_move_server.zones import mask

OCCUPIED = 50  # a cell value from here up is an obstacle (the sim's and costmap_2d's middle)
START_SEARCH = 0.5  # m: how far from the robot a cell it can stand on is looked for
TARGET_SLACK = 2  # cells beyond the robot's radius a wall-side group's target may lie from the group
EPSILON = 1e-6  # 0.15 / 0.05 is not quite 3 in floating point


@dataclass(frozen=True)
class Frontier:
    """A group of frontier cells, and the cell the robot goes to to see past it.

    ``target`` is None (``distance`` and ``cost`` infinite) when no reachable cell serves the group.
    """

    target: Optional[tuple]  # (x, y), map frame: the centre of a reachable cell the robot can stand on
    size: int  # frontier cells in the group
    centroid: tuple  # (x, y) of the group's cells: for display only, it may lie in a wall
    distance: float  # m, straight line from the robot to the target
    cost: float  # lower is better: distance - gain * size in metres (see survey)


@dataclass(frozen=True)
class Survey:
    """What one look at the map found: the frontiers to go to, best first, and how much is known."""

    frontiers: tuple  # reachable groups, lowest cost first, blacklisted ones left out
    unreachable: tuple  # groups no reachable cell serves (seen through a gap narrower than the robot)
    blacklisted: int  # groups left out because a blacklisted point lies near their target
    known_m2: float  # area of the known cells (free and occupied)
    free_m2: float  # area of the cells the robot can reach (free, outside the inflation)
    start: Optional[tuple]  # (x, y) of the cell reachability grew from; None: off the map or boxed in


def as_array(grid):
    """The grid's cells as an int8 ``(height, width)`` array, row 0 at the bottom: a view, no copy."""
    return np.frombuffer(grid.cells, dtype=np.int8).reshape(grid.height, grid.width)


def survey(grid, robot_xy, radius, blacklist=(), blacklist_radius=0.5, min_size=0.3, gain=1.0):
    """The frontiers of ``grid`` for a round robot of ``radius`` metres at ``robot_xy``.

    Groups smaller than ``min_size`` metres (``min_size / resolution`` cells) are laser noise and
    dropped. A group whose target lies within ``blacklist_radius`` of a point of ``blacklist``
    (goals that failed) is left out and counted. The cost is explore_lite's, ``potential_scale *
    distance - gain_scale * size`` (both in metres), divided by ``potential_scale``: one of its two
    scales is redundant, so ``gain`` is the one knob. Its default, 1, makes a metre of frontier worth
    a metre of driving: a doorway-wide opening (0.9 m) wins over a 0.3 m crumb up to 0.6 m nearer
    than it, while distances across a flat (5-20 m) still outweigh openings (1-3 m), so the robot
    finishes the region it is in before crossing the flat. explore_lite's defaults (3 and 1) are
    ``gain`` 1/3: a crumb 0.2 m nearer than a doorway beside it wins, and the robot picks at crumbs.
    """
    _check_inputs(grid, robot_xy, radius)
    window = _Window.of(grid)
    if window is None:
        return Survey((), (), 0, 0.0, 0.0, None)
    reach, start = _reachable(window, robot_xy, radius)
    found, unreachable, blacklisted = [], [], 0
    for rows, cols in _groups(window, min_size / grid.resolution - EPSILON):
        frontier = _frontier(window, reach, rows, cols, robot_xy, radius, gain)
        if frontier.target is None:
            unreachable.append(frontier)
        elif _near_any(frontier.target, blacklist, blacklist_radius):
            blacklisted += 1
        else:
            found.append(frontier)
    found.sort(key=lambda f: (f.cost, f.distance, f.target))
    unreachable.sort(key=lambda f: (-f.size, f.centroid))
    cell_area = grid.resolution ** 2
    return Survey(tuple(found), tuple(unreachable), blacklisted, window.known_cells * cell_area,
                  int(np.count_nonzero(reach)) * cell_area, None if start is None else window.point(*start))


def walled(grid, zones, skip=()):
    """``grid`` with the enabled ``zones`` (but those named in ``skip``) as walls: their cells occupied.

    What the explorer surveys while mapping (docs/zones.md): no frontier beyond a virtual wall or
    inside a no-go zone is reachable, so none is driven to. The grid itself when no zone is on."""
    if not any(zone.enabled and zone.name not in skip for zone in zones):
        return grid
    lethal = np.frombuffer(mask.cells(zones, grid.width, grid.height, grid.resolution, grid.origin_x,
                                      grid.origin_y, grid.origin_yaw, skip), dtype=np.uint8) == mask.LETHAL
    cells = np.frombuffer(grid.cells, dtype=np.int8).copy()
    cells[lethal] = mask.LETHAL
    return dataclasses.replace(grid, cells=cells.tobytes())


def reachable_free(grid, start_xy, radius):
    """A ``(height, width)`` bool array: the cells a robot of ``radius`` at ``start_xy`` can reach.

    The same rule as :func:`survey`'s: known free cells outside the inflation, 4-connected to the
    start (the robot's cell, or the nearest such cell within 0.5 m). All False when there is none.
    """
    _check_inputs(grid, start_xy, radius)
    reachable = np.zeros((grid.height, grid.width), dtype=bool)
    window = _Window.of(grid)
    if window is not None:
        window.paste(reachable, _reachable(window, start_xy, radius)[0])
    return reachable


def label(mask, connectivity=4):
    """The connected components of a 2-D mask's True cells: ``(labels, count)``.

    ``labels`` is an int32 array of the mask's shape: 0 off the mask, 1..count on it, numbered in the
    order of each component's first cell in row-major order (as ``scipy.ndimage.label`` numbers
    them). ``connectivity`` 4 joins cells sharing a side, 8 also cells sharing a corner. The work is
    on runs of True cells along rows: runs of neighbouring rows that touch are joined, and the run
    graph is resolved by vectorised union-find (:func:`_roots`), never a Python loop over cells.
    """
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim != 2 or connectivity not in (4, 8):
        raise ValueError("label takes a 2-D mask and connectivity 4 or 8, got {}-D and {!r}".format(
            mask.ndim, connectivity))
    height, width = mask.shape
    stride = width + 1  # a False column after each row: no run crosses from one row to the next
    cells = np.zeros((height, stride), dtype=bool)
    cells[:, :width] = mask
    cells = cells.ravel()
    starts = cells.copy()
    starts[1:] &= ~cells[:-1]
    run_of = np.cumsum(starts) - 1  # a cell's run number (meaningful on the mask only)
    runs = int(run_of[-1]) + 1 if run_of.size else 0
    if runs == 0:
        return np.zeros(mask.shape, dtype=np.int32), 0
    steps = (stride,) if connectivity == 4 else (stride - 1, stride, stride + 1)
    upper, lower = _touching_runs(cells, run_of, steps)
    _, component = np.unique(_roots(runs, upper, lower), return_inverse=True)
    labels = np.zeros(cells.shape, dtype=np.int32)
    labels[cells] = component[run_of[cells]] + 1
    return np.ascontiguousarray(labels.reshape(height, stride)[:, :width]), int(component.max()) + 1


def _touching_runs(cells, run_of, steps):
    """(upper, lower) run pairs where a cell and the cell ``step`` after it (the next row's) are on.

    Two runs overlap along one stretch of cells, so only each stretch's first cell gives a pair.
    """
    upper, lower = [], []
    for step in steps:
        both = cells[:-step] & cells[step:]
        first = both.copy()
        first[1:] &= ~both[:-1]
        at = np.flatnonzero(first)
        upper.append(run_of[at])
        lower.append(run_of[at + step])
    return np.concatenate(upper), np.concatenate(lower)


def _roots(count, a, b):
    """For each of ``count`` nodes joined by the edges ``a[i]``–``b[i]``, its component's smallest node.

    Vectorised hooking and pointer jumping (Shiloach–Vishkin style): each round, for every edge
    still joining two trees, the larger root is hooked under the smaller (a root written by several
    edges keeps one of them: the others come back next round), then every node points straight at
    its root. Parents only ever point down, so there are no cycles, and few rounds are needed.
    """
    parent = np.arange(count)
    while a.size:
        root_a, root_b = parent[a], parent[b]
        apart = root_a != root_b
        a, b, root_a, root_b = a[apart], b[apart], root_a[apart], root_b[apart]
        parent[np.maximum(root_a, root_b)] = np.minimum(root_a, root_b)
        while True:
            grand = parent[parent]
            if np.array_equal(grand, parent):
                break
            parent = grand
    return parent


def _check_inputs(grid, xy, radius):
    if not (radius >= 0 and math.isfinite(radius)):
        raise ValueError("a robot's radius must be 0 or more metres, got {!r}".format(radius))
    if abs(grid.origin_yaw) > EPSILON:
        raise ValueError("frontiers need a map whose origin is not rotated (yaw 0), got yaw {!r}".format(
            grid.origin_yaw))
    if not all(math.isfinite(v) for v in xy):
        raise ValueError("a robot position must be finite numbers, got {!r}".format(tuple(xy)))


class _Window:
    """The known part of a grid: the bounding box of its known cells plus one cell all round.

    Box cells beyond the canvas are occupied here: the edge is no unknown space to explore, and it
    stops the robot as a wall would (``sim/costmap.py`` pads its grid so; see :meth:`clear_of_edge`).
    """

    def __init__(self, grid, cells, rows, cols):
        self.resolution = grid.resolution
        self.origin = (grid.origin_x, grid.origin_y)
        self.shape = (grid.height, grid.width)
        self.top, self.left = rows[0] - 1, cols[0] - 1  # canvas row and column of box cell (0, 0)
        values = np.full((rows[1] - rows[0] + 3, cols[1] - cols[0] + 3), 100, dtype=np.int8)
        r0, r1 = max(self.top, 0), min(rows[1] + 2, grid.height)
        c0, c1 = max(self.left, 0), min(cols[1] + 2, grid.width)
        self.canvas_part = (slice(r0, r1), slice(c0, c1))
        self.box_part = (slice(r0 - self.top, r1 - self.top), slice(c0 - self.left, c1 - self.left))
        values[self.box_part] = cells[self.canvas_part]
        self.unknown = values < 0
        self.occupied = values >= OCCUPIED
        self.free = ~(self.unknown | self.occupied)
        self.known_cells = int(np.count_nonzero(~self.unknown[1:-1, 1:-1]))

    @classmethod
    def of(cls, grid):
        """The window on ``grid``'s known cells; None when it has none."""
        cells = as_array(grid)
        rows = np.flatnonzero(cells.max(axis=1) >= 0)  # a SIMD reduction: ~2 ms for 4000 x 4000
        if not rows.size:
            return None
        cols = np.flatnonzero(cells[rows[0]:rows[-1] + 1].max(axis=0) >= 0)
        return cls(grid, cells, (int(rows[0]), int(rows[-1])), (int(cols[0]), int(cols[-1])))

    def cell_of(self, x, y):
        """The box (row, col) of the cell under map point (x, y), maybe outside the box; None off the canvas."""
        col = int(math.floor((x - self.origin[0]) / self.resolution))
        row = int(math.floor((y - self.origin[1]) / self.resolution))
        if not (0 <= row < self.shape[0] and 0 <= col < self.shape[1]):
            return None
        return row - self.top, col - self.left

    def centres(self, rows, cols):
        """Map-frame (x, y) of the centres of box cells (numbers or arrays)."""
        return (self.origin[0] + (cols + self.left + 0.5) * self.resolution,
                self.origin[1] + (rows + self.top + 0.5) * self.resolution)

    def point(self, row, col):
        """The map-frame centre of one box cell, as a tuple of floats."""
        x, y = self.centres(row, col)
        return float(x), float(y)

    def clear_of_edge(self, reach):
        """Box cells farther than ``reach`` cells from the canvas edge (a wall one cell beyond it).

        The box's ring holds that wall where the box touches the edge; this also covers known cells
        a few cells short of it, whose edge lies beyond the box.
        """
        r2 = reach * reach + EPSILON
        height, width = self.free.shape

        def clear(first, count, size):
            index = np.arange(first, first + count)
            return ((index + 1) ** 2 > r2) & ((size - index) ** 2 > r2)
        return clear(self.top, height, self.shape[0])[:, None] & clear(self.left, width, self.shape[1])[None, :]

    def paste(self, canvas, box_array):
        """Copy a box-shaped array into the matching part of a canvas-shaped one."""
        canvas[self.canvas_part] = box_array[self.box_part]


def _reachable(window, robot_xy, radius):
    """(mask of the box cells the robot reaches, its start cell or None)."""
    reach = radius / window.resolution + 0.5
    standable = window.free & ~_dilate(window.occupied, reach) & window.clear_of_edge(reach)
    start = _start_cell(window, standable, robot_xy)
    if start is None:
        return np.zeros_like(standable), None
    labels, _ = label(standable, 4)
    return labels == labels[start], start


def _start_cell(window, standable, xy):
    """The robot's cell if it can stand there, else the nearest such cell within START_SEARCH.

    A robot may stand closer to a wall than its inflation allows (it drove there, or was put
    there), and gmapping may not have marked its own cell yet; None when nothing is near.
    """
    cell = window.cell_of(*xy)
    if cell is None:
        return None
    row, col = cell
    height, width = standable.shape
    if 0 <= row < height and 0 <= col < width and standable[row, col]:
        return cell
    span = int(math.ceil(START_SEARCH / window.resolution)) + 1
    r0, c0 = max(row - span, 0), max(col - span, 0)
    rows, cols = np.nonzero(standable[r0:max(row + span + 1, 0), c0:max(col + span + 1, 0)])
    if not rows.size:
        return None
    x, y = window.centres(rows + r0, cols + c0)
    distance = np.hypot(x - xy[0], y - xy[1])
    best = int(np.argmin(distance))
    if distance[best] > START_SEARCH + EPSILON:
        return None
    return int(rows[best]) + r0, int(cols[best]) + c0


def _dilate(mask, reach):
    """The cells whose centre lies within ``reach`` cells of a True cell's centre (a disk dilation).

    Separable by the disk's rows: the mask is dilated along rows once per half-width (each from the
    previous: two shifts), and each row of the disk is one vertical shift of its row dilation.
    """
    r2 = reach * reach + EPSILON
    rows = int(math.floor(math.sqrt(r2)))
    half = [int(math.floor(math.sqrt(max(r2 - dy * dy, 0.0)))) for dy in range(rows + 1)]
    along = [mask]
    for _ in range(half[0]):
        grown = along[-1].copy()
        grown[:, 1:] |= along[-1][:, :-1]
        grown[:, :-1] |= along[-1][:, 1:]
        along.append(grown)
    out = along[half[0]].copy()
    for dy in range(1, min(rows, mask.shape[0] - 1) + 1):
        out[dy:] |= along[half[dy]][:-dy]
        out[:-dy] |= along[half[dy]][dy:]
    return out


def _frontier_cells(window):
    """Known free cells with an unknown 4-neighbour (the box's outer ring is unknown or off-canvas)."""
    unknown = window.unknown
    beside = np.zeros_like(unknown)
    beside[1:] |= unknown[:-1]
    beside[:-1] |= unknown[1:]
    beside[:, 1:] |= unknown[:, :-1]
    beside[:, :-1] |= unknown[:, 1:]
    return window.free & beside


def _groups(window, min_cells):
    """(rows, cols) of each 8-connected group of at least ``min_cells`` frontier cells."""
    labels, count = label(_frontier_cells(window), 8)
    rows, cols = np.nonzero(labels)
    ids = labels[rows, cols] - 1
    order = np.argsort(ids, kind="stable")
    rows, cols, sizes = rows[order], cols[order], np.bincount(ids, minlength=count)
    ends = np.cumsum(sizes)
    return [(rows[end - size:end], cols[end - size:end])
            for size, end in zip(sizes.tolist(), ends.tolist()) if size >= min_cells]


def _frontier(window, reach, rows, cols, robot_xy, radius, gain):
    """The :class:`Frontier` of one group of cells."""
    centre = (rows.mean(), cols.mean())
    target = _target(window, reach, rows, cols, centre, radius)
    size = int(rows.size)
    if target is None:
        return Frontier(None, size, window.point(*centre), math.inf, math.inf)
    target = window.point(*target)
    distance = math.hypot(target[0] - robot_xy[0], target[1] - robot_xy[1])
    return Frontier(target, size, window.point(*centre), distance, distance - gain * size * window.resolution)


def _target(window, reach, rows, cols, centre, radius):
    """The box cell the robot goes to for a group: None when no reachable cell serves it.

    The group's reachable cell nearest its centroid; when none of its cells is reachable (a
    frontier along a wall lies in the wall's inflation), the reachable cell nearest the centroid
    among those within ``radius`` + TARGET_SLACK cells of the group, so one a robot's radius off the wall.
    """
    on = reach[rows, cols]
    if on.any():
        return _nearest(rows[on], cols[on], centre)
    within = radius / window.resolution + TARGET_SLACK
    span = int(math.ceil(within))
    r0, c0 = max(int(rows.min()) - span, 0), max(int(cols.min()) - span, 0)
    r1, c1 = int(rows.max()) + span + 1, int(cols.max()) + span + 1
    group = np.zeros(reach[r0:r1, c0:c1].shape, dtype=bool)
    group[rows - r0, cols - c0] = True
    near_rows, near_cols = np.nonzero(_dilate(group, within) & reach[r0:r1, c0:c1])
    if not near_rows.size:
        return None
    return _nearest(near_rows + r0, near_cols + c0, centre)


def _nearest(rows, cols, centre):
    """The (row, col) among the cells nearest to ``centre`` (row, col); the first on a tie."""
    best = int(np.argmin((rows - centre[0]) ** 2 + (cols - centre[1]) ** 2))
    return int(rows[best]), int(cols[best])


def _near_any(point, others, distance):
    """Whether one of the (x, y) ``others`` lies within ``distance`` metres of ``point``."""
    return any(math.hypot(point[0] - x, point[1] - y) <= distance for x, y in others)
