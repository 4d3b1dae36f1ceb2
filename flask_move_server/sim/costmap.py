"""The occupancy map as a round robot sees it: where its centre may go, and at what cost.

A cell is *lethal* when an obstacle (an occupied or unknown cell, or the edge
of the map) lies within the robot's radius of it (plus half a cell, as the
distance runs between cell centres): the robot's centre there would put its
body into the obstacle. Cells within ``radius + margin`` are
allowed but cost more, so planned paths keep a safety distance where there is
room (the inflation layer of move_base's costmap, simplified). Pure: no rospy.

The grid is padded with a ring of lethal cells, so neighbour lookups never
leave the arrays (the planner relies on it).
"""

import math

LETHAL = 255
MARGIN_COST = 4  # extra cost per step in the margin zone, relative to a free step of 1


class Costmap:
    """Lethal cells and margin costs of a map for a robot of ``radius`` metres."""

    def __init__(self, grid, radius, margin=0.0):
        self.grid = grid
        self.radius = radius
        self.margin = margin
        self.width = grid.width + 2  # padded
        self.height = grid.height + 2
        self.resolution = grid.resolution
        self.obstacles = self._padded_obstacles(grid)
        self.cost = self._inflate()

    def _padded_obstacles(self, grid):
        w, h, W = grid.width, grid.height, self.width
        blocked = grid.blocked()
        padded = bytearray(b"\x01") * (W * self.height)
        for row in range(h):
            start = (row + 1) * W + 1
            padded[start:start + w] = blocked[row * w:(row + 1) * w]
        return padded

    def _inflate(self):
        """Cost of every cell from its distance to the nearest obstacle (stamped from obstacle edges)."""
        W, H, res = self.width, self.height, self.resolution
        # Distances run between cell centres: half a cell more keeps the body out of the obstacle cell itself.
        lethal_r2 = (self.radius / res + 0.5) ** 2 + 1e-6  # + 1e-6: 0.15 / 0.05 is not quite 3 in floating point
        margin_r2 = ((self.radius + self.margin) / res + 0.5) ** 2 + 1e-6
        reach = int(math.ceil(math.sqrt(margin_r2)))
        offsets = _disk_offsets(reach, margin_r2, W)
        obstacles = self.obstacles
        cost = bytearray(W * H)
        for p in _edge_cells(obstacles, W, H):
            col, row = p % W, p // W
            near_edge = col < reach or row < reach or col >= W - reach or row >= H - reach
            for off, dcol, drow, d2 in offsets:
                if near_edge and not (0 <= col + dcol < W and 0 <= row + drow < H):
                    continue
                q = p + off
                if cost[q] != LETHAL:
                    cost[q] = LETHAL if d2 <= lethal_r2 else MARGIN_COST
        for p in range(W * H):
            if obstacles[p]:
                cost[p] = LETHAL
        return cost

    def index(self, x, y):
        """The padded-grid index of the cell under (x, y), or None outside the map."""
        cell = self.grid.cell_of(x, y)
        return None if cell is None else (cell[1] + 1) * self.width + cell[0] + 1

    def point(self, index):
        """The map-frame centre of padded cell ``index``."""
        row, col = divmod(index, self.width)
        return self.grid.center_of(col - 1, row - 1)

    def lethal_at(self, x, y):
        """True when the robot's body would overlap an obstacle with its centre at (x, y) (or it is off the map)."""
        index = self.index(x, y)
        return index is None or self.cost[index] == LETHAL

    def touches(self, x, y):
        """True when a disk of ``radius`` centred at (x, y) overlaps an obstacle cell's square (or the map's edge).

        The body's own test (``body.py``), exact where :meth:`lethal_at` is quantized to cell centres:
        with that, a robot that came to rest beside a corner by an arc could stand in a free cell whose
        every neighbour along its heading is lethal, and neither back out nor pull out straight (the
        explorer ended ``stuck`` so beside the dining table and a door jamb). Exact, the distance to an
        obstacle is continuous, so a move that keeps the robot as far from it is never refused."""
        index = self.index(x, y)
        if index is None or self.obstacles[index]:
            return True
        res, width, obstacles = self.resolution, self.width, self.obstacles
        left, bottom = self.grid.origin_x - res, self.grid.origin_y - res  # padded cell (0, 0)'s corner
        row0, col0 = divmod(index, width)
        reach = int(math.ceil(self.radius / res)) + 1
        r2 = self.radius * self.radius
        for row in range(max(0, row0 - reach), min(self.height, row0 + reach + 1)):
            low = bottom + row * res
            dy = max(low - y, 0.0, y - low - res)
            if dy * dy >= r2:
                continue
            base = row * width
            for col in range(max(0, col0 - reach), min(width, col0 + reach + 1)):
                if obstacles[base + col]:
                    near = left + col * res
                    dx = max(near - x, 0.0, x - near - res)
                    if dx * dx + dy * dy < r2:
                        return True
        return False


def _disk_offsets(reach, r2, width):
    """(index offset, dcol, drow, squared distance) of every cell within sqrt(r2) cells, nearest first."""
    offsets = []
    for drow in range(-reach, reach + 1):
        for dcol in range(-reach, reach + 1):
            d2 = dcol * dcol + drow * drow
            if d2 <= r2:
                offsets.append((drow * width + dcol, dcol, drow, d2))
    offsets.sort(key=lambda o: o[3])
    return offsets


def _edge_cells(obstacles, width, height):
    """Obstacle cells with a free 4-neighbour: the only ones whose disks reach free space."""
    for p in range(width, width * (height - 1)):
        if obstacles[p] and not (obstacles[p - 1] and obstacles[p + 1] and obstacles[p - width]
                                 and obstacles[p + width]):
            yield p
    # The padding ring itself borders the map's first and last rows/columns.
    for p in list(range(width)) + list(range(width * (height - 1), width * height)):
        yield p
