"""Global path planning on a :class:`~flask_move_server.sim.costmap.Costmap`: A*, then shortcuts.

A* over the 8-connected grid (octile heuristic, so the path is the cheapest
one), lethal cells forbidden and margin cells dearer; the cell path is then
pulled tight by keeping only the corners a straight line cannot skip without
entering dearer cells. The result is a short list of map-frame points from
the start to the goal, for the path follower.

Pure: no rospy. Failures raise PlanningFailed with a reason a user can act on.
"""

import heapq
import math
from array import array

from flask_move_server.core.errors import PlanningFailed
from flask_move_server.sim.costmap import LETHAL

SQRT2 = math.sqrt(2.0)


class Planner:
    """Plans collision-free paths for the robot on one costmap.

    ``navfn_start``: plan from where the robot is localized as navfn does (navfn_ros.cpp
    ``clearRobotCell`` frees the robot's own cell only, and the potential spreads to the 4 neighbours
    of a cell below ``COST_OBS``): a robot localized in a lethal cell whose 4 neighbours are all lethal
    gets no plan ("Failed to find a valid plan"), as a real robot whose localized pose slid into a wall.
    Otherwise (the mapping stand-in's planner, whose walls reach a cell further than the body) the
    nearest open cell is planned from.
    """

    def __init__(self, costmap, navfn_start=False):
        self.costmap = costmap
        self.navfn_start = navfn_start
        w = costmap.width
        # (index offset, cost of the step into a cell of each cost value): 8-connected, margin cells dearer
        self._steps = [(off, [length * (1 + c) for c in range(256)]) for off, length in (
            (1, 1.0), (-1, 1.0), (w, 1.0), (-w, 1.0), (w + 1, SQRT2), (w - 1, SQRT2), (-w + 1, SQRT2), (-w - 1, SQRT2))]

    def check_goal(self, x, y):
        """Raise PlanningFailed when no robot could ever stand at (x, y)."""
        index = self.costmap.index(x, y)
        if index is None:
            raise PlanningFailed("outside_map", "the goal ({:.2f}, {:.2f}) is outside the map".format(x, y))
        if self.costmap.cost[index] == LETHAL:
            raise PlanningFailed(
                "occupied", "the goal ({:.2f}, {:.2f}) is in or too close to an obstacle for the robot".format(x, y))
        return index

    def plan(self, start, goal):
        """A collision-free path from ``start`` (x, y) to ``goal`` (x, y): a list of points, both ends included."""
        goal_index = self.check_goal(*goal)
        start_index = self.costmap.index(*start)
        if start_index is None:
            raise PlanningFailed("outside_map", "the robot is outside the map")
        escape = self._open_neighbour(start_index) if self.navfn_start else self._nearest_open(start_index)
        if escape is None and self.navfn_start:
            raise PlanningFailed("no_plan", "Failed to find a valid plan: the robot is localized with its "
                                 "footprint on an obstacle of the map ({:.2f}, {:.2f})".format(*start))
        cells = None if escape is None else self._search(escape, goal_index)
        if cells is None:
            raise PlanningFailed(
                "unreachable", "no path to ({:.2f}, {:.2f}): the goal is walled off from the robot".format(*goal))
        if escape != start_index:
            cells = [start_index] + cells
        corners = self._shortcut(cells)
        points = [self.costmap.point(p) for p in corners]
        points[0], points[-1] = tuple(start), tuple(goal)
        return points

    def _open_neighbour(self, start):
        """``start`` when it is open, else one of its 4 neighbours that is (navfn's rule), or None."""
        cost, width = self.costmap.cost, self.costmap.width
        for p in (start, start + 1, start - 1, start + width, start - width):
            if cost[p] != LETHAL:
                return p
        return None

    def _nearest_open(self, start, reach=20):
        """``start``, or the nearest non-lethal cell when the robot stands too close to an obstacle."""
        cost, width = self.costmap.cost, self.costmap.width
        if cost[start] != LETHAL:
            return start
        best = None
        row, col = divmod(start, width)
        height = len(cost) // width
        for r in range(max(0, row - reach), min(height, row + reach + 1)):
            for c in range(max(0, col - reach), min(width, col + reach + 1)):
                d2 = (r - row) ** 2 + (c - col) ** 2
                if cost[r * width + c] != LETHAL and (best is None or d2 < best[0]):
                    best = (d2, r * width + c)
        return None if best is None else best[1]

    def _search(self, start, goal):
        """A* from ``start`` to ``goal`` (padded indices); the cell indices of the path, or None."""
        width = self.costmap.width
        work = bytearray(self.costmap.cost)  # LETHAL also marks the cells already expanded
        g = array("d", [math.inf]) * len(work)
        parent = array("l", [-1]) * len(work)
        goal_row, goal_col = divmod(goal, width)
        diagonal = SQRT2 - 2.0
        g[start] = 0.0
        heap = [(0.0, start)]
        pop, push = heapq.heappop, heapq.heappush
        while heap:
            _, p = pop(heap)
            if p == goal:
                return _walk_back(parent, goal)
            if work[p] == LETHAL:
                continue
            work[p] = LETHAL
            gp = g[p]
            for off, step_cost in self._steps:
                q = p + off
                c = work[q]
                if c == LETHAL:
                    continue
                ng = gp + step_cost[c]
                if ng < g[q]:
                    g[q] = ng
                    parent[q] = p
                    row, col = divmod(q, width)
                    dr = row - goal_row if row > goal_row else goal_row - row
                    dc = col - goal_col if col > goal_col else goal_col - col
                    push(heap, (ng + dr + dc + diagonal * (dr if dr < dc else dc), q))
        return None

    def _shortcut(self, cells):
        """Keep the corners of the cell path that a straight line cannot skip at no extra cost.

        From each corner, the farthest cell still in straight sight is found by galloping then
        bisecting, so a long path costs a few line checks per corner, not one per cell.
        """
        last = len(cells) - 1
        corners = [cells[0]]
        a = 0
        while a < last:
            seen, blocked, step = a + 1, None, 1
            while blocked is None and seen < last:
                j = min(seen + step, last)
                if self._line_clear(cells[a], cells[j]):
                    seen, step = j, step * 2
                else:
                    blocked = j
            while blocked is not None and blocked - seen > 1:
                mid = (seen + blocked) // 2
                if self._line_clear(cells[a], cells[mid]):
                    seen = mid
                else:
                    blocked = mid
            corners.append(cells[seen])
            a = seen
        return corners

    def _line_clear(self, a, b):
        """True when the straight line a→b crosses no cell dearer than its ends (nor any lethal one)."""
        cost, width = self.costmap.cost, self.costmap.width
        limit = max(cost[a], cost[b])
        ar, ac = divmod(a, width)
        br, bc = divmod(b, width)
        n = 2 * max(abs(br - ar), abs(bc - ac))
        for k in range(1, n):
            t = k / n
            q = int(ar + (br - ar) * t + 0.5) * width + int(ac + (bc - ac) * t + 0.5)
            c = cost[q]
            if c > limit or c == LETHAL:
                return False
        return True


def _walk_back(parent, goal):
    path = [goal]
    p = parent[goal]
    while p != -1:
        path.append(p)
        p = parent[p]
    path.reverse()
    return path


def path_length(points):
    """Length in metres of a polyline of (x, y) points."""
    return sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(points, points[1:]))
