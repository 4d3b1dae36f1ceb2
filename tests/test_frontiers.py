"""The explorer's pure core (explore/frontiers.py): frontiers, targets the robot can reach, labels.

Maps are drawn as ASCII art at 10 cm a cell, top line = top row: '#' occupied, '.' free, '?' or
' ' unknown, 'R' the robot (on a free cell). The robot's radius is 0.2 m: 2.5 cells with the half
cell, so it stands on cells at least 3 cells (straight) from every wall. Every survey here checks
that each target is a free cell outside every wall's inflation that the robot can reach.
"""

import math
import os
from collections import deque

import numpy as np
import pytest

from flask_move_server.explore import frontiers
from flask_move_server.explore.frontiers import label, reachable_free
from flask_move_server.maps import mapfile
from flask_move_server.zones import make_zone

RES, RADIUS = 0.1, 0.2
CODES = {"#": 100, ".": 0, "R": 0, "?": -1, " ": -1}
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def drawn(art, origin=(0.0, 0.0)):
    """(Grid, robot (x, y) or None) from ASCII art; short lines are padded with unknown cells."""
    lines = art.strip("\n").split("\n")
    width = max(len(line) for line in lines)
    values, robot = [], None
    for row, line in enumerate(reversed(lines)):
        for col, char in enumerate(line.ljust(width)):
            values.append(CODES[char])
            if char == "R":
                robot = (origin[0] + (col + 0.5) * RES, origin[1] + (row + 0.5) * RES)
    return mapfile.Grid(width, len(lines), RES, origin[0], origin[1], values), robot


def survey(grid, robot, **options):
    """frontiers.survey, with every target checked: a reachable free cell outside the inflation."""
    found = frontiers.survey(grid, robot, RADIUS, **options)
    reachable = reachable_free(grid, robot, RADIUS)
    for frontier in found.frontiers:
        assert_standable(grid, frontier.target)
        col, row = cell_of(grid, frontier.target)
        assert reachable[row, col], frontier
        assert frontier.distance == pytest.approx(math.hypot(
            frontier.target[0] - robot[0], frontier.target[1] - robot[1]))
    for frontier in found.unreachable:
        assert frontier.target is None and frontier.distance == math.inf
    return found


def cell_of(grid, xy):
    return int(math.floor((xy[0] - grid.origin_x) / RES)), int(math.floor((xy[1] - grid.origin_y) / RES))


def assert_standable(grid, xy):
    """The cell under xy is free, and no occupied cell lies within the robot's radius (+ half a cell)."""
    col, row = cell_of(grid, xy)
    cells = frontiers.as_array(grid)
    assert 0 <= cells[row, col] < 50, "target {} is not a free cell".format(xy)
    walls_row, walls_col = np.nonzero(cells >= 50)
    nearest = np.hypot(walls_row - row, walls_col - col).min() if walls_row.size else math.inf
    assert nearest > RADIUS / RES + 0.5, "target {} is {} cells from a wall".format(xy, nearest)


OPEN_SIDE = """
###############
#.............????
#.............????
#.............????
#.....R.......????
#.............????
#.............????
#.............????
###############
"""


def test_an_open_room_has_one_frontier_on_its_unseen_side_with_a_reachable_target():
    grid, robot = drawn(OPEN_SIDE)
    found = survey(grid, robot)
    assert len(found.frontiers) == 1 and found.unreachable == ()
    frontier = found.frontiers[0]
    assert frontier.size == 7
    assert frontier.target == pytest.approx((1.35, 0.45))  # the free column beside the unknown, middle row
    assert frontier.centroid == pytest.approx((1.35, 0.45))
    assert found.start == pytest.approx(robot)


def doorway(door_rows):
    """Two rooms joined by a door ``door_rows`` cells wide; the far room's right side unseen."""
    lines = ["#" * 21]
    for row in range(14):
        wall = "." if 4 <= row < 4 + door_rows else "#"
        lines.append("#" + ("..R......" if row == 2 else ".........") + wall + ".........????")
    lines.append("#" * 21)
    return drawn("\n".join(lines))


def test_a_room_behind_a_door_wider_than_the_robot_is_reachable_through_it():
    grid, robot = doorway(5)  # 0.5 m > 2 x 0.2 m
    found = survey(grid, robot)
    assert len(found.frontiers) == 1 and found.unreachable == ()
    assert found.frontiers[0].target[0] > 1.1  # in the far room
    assert found.frontiers[0].size == 14


def test_a_room_seen_through_a_gap_narrower_than_the_robot_is_unreachable():
    grid, robot = doorway(3)  # 0.3 m < 2 x 0.2 m
    found = survey(grid, robot)
    assert found.frontiers == ()
    assert len(found.unreachable) == 1
    assert found.unreachable[0].size == 14 and found.unreachable[0].cost == math.inf


def test_a_virtual_wall_across_the_door_makes_the_room_behind_it_unreachable_unless_off_or_skipped():
    grid, robot = doorway(5)
    wall = make_zone("door", {"kind": "wall", "line": [[1.05, 0.2], [1.05, 1.1]]})
    walled = frontiers.walled(grid, [wall])
    assert walled.cells != grid.cells and (walled.width, walled.height) == (grid.width, grid.height)
    found = survey(walled, robot)
    assert found.frontiers == () and len(found.unreachable) == 1
    for unwalled in (frontiers.walled(grid, [wall.switched(False)]), frontiers.walled(grid, [wall], skip=["door"])):
        assert unwalled is grid
        assert len(survey(unwalled, robot).frontiers) == 1


WALL_SIDE_HOLE = """
#################
#.........??????#
#...............#
#...............#
#...............#
#.......R.......#
#...............#
#...............#
#################
"""


def test_a_frontier_along_a_wall_gets_a_target_a_robot_radius_off_the_wall():
    grid, robot = drawn(WALL_SIDE_HOLE)  # the laser grazed the top wall and left a strip unknown
    found = survey(grid, robot)
    assert len(found.frontiers) == 1
    target = found.frontiers[0].target
    top_wall_bottom = 8 * RES  # the top wall is row 8
    assert top_wall_bottom - target[1] > RADIUS
    assert 1.0 < target[0] < 1.6  # below the unknown strip


NEAR_THE_WALL = """
###############
#.............????
#.............????
#.............????
#.............????
#.............????
#.............????
#R............????
###############
"""


def test_a_robot_in_a_walls_inflation_still_gets_a_start_and_frontiers():
    grid, robot = drawn(NEAR_THE_WALL)  # its centre 0.15 m from two walls: inside their inflation
    found = survey(grid, robot)
    assert found.start is not None and found.start != pytest.approx(robot)
    assert math.hypot(found.start[0] - robot[0], found.start[1] - robot[1]) <= 0.5
    assert len(found.frontiers) == 1


def test_a_robot_boxed_in_or_off_the_map_has_no_start_and_every_group_unreachable():
    grid, robot = drawn(OPEN_SIDE)
    for where in [(-5.0, 0.4), (50.0, 50.0)]:
        found = frontiers.survey(grid, where, RADIUS)
        assert found.start is None and found.frontiers == () and found.free_m2 == 0.0
        assert len(found.unreachable) == 1
    closet = drawn("""
#####
#.R.#
#####
#...?
#...?
#####
""")[0]
    assert frontiers.survey(closet, (0.25, 0.45), RADIUS).start is None
    assert not reachable_free(closet, (0.25, 0.45), RADIUS).any()


def test_a_blacklisted_target_leaves_its_group_out_and_is_counted():
    grid, robot = drawn(OPEN_SIDE)
    target = survey(grid, robot).frontiers[0].target
    near = survey(grid, robot, blacklist=[(target[0] - 0.3, target[1] + 0.2)], blacklist_radius=0.5)
    assert near.frontiers == () and near.blacklisted == 1 and near.unreachable == ()
    far = survey(grid, robot, blacklist=[(target[0] - 1.0, target[1])], blacklist_radius=0.5)
    assert len(far.frontiers) == 1 and far.blacklisted == 0


CLOSED_ROOM = """
############
#..........#
#..........#
#....R.....#
#..........#
#..........#
#..........#
############
"""


def test_a_fully_explored_closed_room_has_no_frontiers():
    grid, robot = drawn(CLOSED_ROOM)
    found = survey(grid, robot)
    assert found.frontiers == () and found.unreachable == () and found.blacklisted == 0


SPECKS = """
############
#..........#
#..........#
?....R.....#
#..........#
#..........#
#?.........#
############
"""


def test_specks_of_unknown_smaller_than_min_size_are_noise():
    grid, robot = drawn(SPECKS)  # an unknown wall cell (1 frontier cell), an unknown corner (2)
    assert survey(grid, robot).frontiers == ()  # min_size 0.3 m: 3 cells, 8-connected
    assert survey(grid, robot).unreachable == ()
    found = survey(grid, robot, min_size=0.1)
    assert sorted(f.size for f in found.frontiers + found.unreachable) == [1, 2]


TO_THE_EDGE = """
###########
#..........
#..........
#....R.....
#..........
#..........
#..........
###########
"""


def test_free_cells_on_the_canvas_edge_are_no_frontier():
    grid, robot = drawn(TO_THE_EDGE)  # no right wall: the free cells reach the canvas edge
    found = survey(grid, robot)
    assert found.frontiers == () and found.unreachable == ()
    reachable = reachable_free(grid, robot, RADIUS)
    assert not reachable[:, -2:].any() and reachable[:, -3].any()  # the edge stops the robot as a wall


def test_the_canvas_edge_stops_the_robot_even_where_unknown_cells_lie_between():
    art = "\n".join(line[:-1] + "?" for line in TO_THE_EDGE.strip("\n").split("\n"))
    grid, robot = drawn(art)  # the last column unknown: the edge 2 cells from the free cells beside it
    reachable = reachable_free(grid, robot, RADIUS)
    assert not reachable[:, -2:].any() and reachable[:, -3].any()
    found = survey(grid, robot)  # the unknown column is on the canvas: a frontier, served from 0.3 m off the edge
    assert len(found.frontiers) == 1 and found.frontiers[0].target[0] == pytest.approx(0.85)


CORRIDOR = """
???################################???
????................R.............????
????..............................????
????..............................????
????..............................????
????..............................????
????..............................????
???################################???
"""


def test_the_nearer_of_two_frontiers_of_one_size_comes_first():
    grid, robot = drawn(CORRIDOR)  # the robot 1.3 m from the right end, 1.6 m from the left
    found = survey(grid, robot)
    assert [f.size for f in found.frontiers] == [6, 6]
    assert [f.target[0] > robot[0] for f in found.frontiers] == [True, False]
    for f in found.frontiers:
        assert f.cost == pytest.approx(f.distance - f.size * RES)


def openings(left, right):
    """A 32 x 14 cell room, the robot in the middle, unknown beyond ``left`` and ``right`` cells of
    its side walls (centred on the robot's row): two frontiers at the same distance, of those sizes."""
    cells = np.full((14, 40), -1, dtype=np.int8)  # 4 unknown columns each side: no canvas edge near
    room = cells[:, 4:-4]
    room[...] = 0
    room[[0, -1], :] = 100
    room[:, [0, -1]] = 100
    room[7 - left // 2:7 - left // 2 + left, 0] = -1
    room[7 - right // 2:7 - right // 2 + right, -1] = -1
    grid = mapfile.Grid(40, 14, RES, 0.0, 0.0, cells.tobytes())
    return grid, (2.0, 0.75)


def test_of_two_frontiers_at_one_distance_the_larger_comes_first_unless_gain_is_zero():
    grid, robot = openings(8, 5)
    found = survey(grid, robot)
    assert [f.size for f in found.frontiers] == [8, 5]
    assert found.frontiers[0].distance == pytest.approx(found.frontiers[1].distance, abs=RES)
    by_distance = survey(grid, robot, gain=0.0)
    assert [f.size for f in by_distance.frontiers] == [5, 8]  # 5 centred on the robot's row, 8 half a cell off


def test_known_and_reachable_areas():
    grid, robot = drawn(CLOSED_ROOM)  # 12 x 8 cells known; 10 x 6 free inside, the robot on 6 x 2 of them
    found = survey(grid, robot)
    assert found.known_m2 == pytest.approx(12 * 8 * RES * RES)
    assert found.free_m2 == pytest.approx((10 - 4) * (6 - 4) * RES * RES)
    assert frontiers.survey(drawn("????\n????")[0], (0.1, 0.1), RADIUS) == frontiers.Survey((), (), 0, 0.0, 0.0, None)


def test_a_map_drawn_anywhere_on_a_large_canvas_surveys_the_same():
    grid, robot = doorway(5)
    small = frontiers.survey(grid, robot, RADIUS)
    assert len(small.frontiers) == 1
    cells, shift = frontiers.as_array(grid), (-3.0, 2.0)  # where the small map's origin lands
    for top, left in [(0, 0), (300 - grid.height, 400 - grid.width), (137, 250)]:
        canvas = np.full((300, 400), -1, dtype=np.int8)
        canvas[top:top + grid.height, left:left + grid.width] = cells
        big = mapfile.Grid(400, 300, RES, shift[0] - left * RES, shift[1] - top * RES, canvas.tobytes())
        moved = (robot[0] + shift[0], robot[1] + shift[1])
        found = frontiers.survey(big, moved, RADIUS)
        assert [f.size for f in found.frontiers] == [f.size for f in small.frontiers]
        for f, g in zip(found.frontiers, small.frontiers):
            assert f.target == pytest.approx((g.target[0] + shift[0], g.target[1] + shift[1]))
        assert found.free_m2 == pytest.approx(small.free_m2) and found.known_m2 == pytest.approx(small.known_m2)


def test_the_demo_flat_lets_the_robot_reach_every_room_but_the_locked_store_room():
    grid = mapfile.load(os.path.join(ROOT, "config", "maps", "demo.yaml"))
    reachable = reachable_free(grid, (0.0, 0.0), 0.15)
    for x, y in [(0.0, 0.0), (8.4, 0.9), (6.2, 4.5), (-0.8, 4.3)]:  # dock, kitchen, bedroom, office
        col, row = int((x - grid.origin_x) / grid.resolution), int((y - grid.origin_y) / grid.resolution)
        assert reachable[row, col], (x, y)
    col, row = int((4.6 - grid.origin_x) / grid.resolution), int((-1.5 - grid.origin_y) / grid.resolution)
    assert not reachable[row, col]
    found = frontiers.survey(grid, (0.0, 0.0), 0.15)
    assert found.frontiers == () and found.start == pytest.approx((0.025, 0.025))


def test_rotated_maps_positions_that_are_no_numbers_and_negative_radii_are_refused():
    grid, robot = drawn(OPEN_SIDE)
    with pytest.raises(ValueError, match="yaw"):
        frontiers.survey(mapfile.Grid(grid.width, grid.height, RES, 0.0, 0.0, grid.cells, origin_yaw=0.3), robot,
                         RADIUS)
    with pytest.raises(ValueError, match="finite"):
        frontiers.survey(grid, (math.nan, 0.0), RADIUS)
    with pytest.raises(ValueError, match="radius"):
        frontiers.survey(grid, robot, -0.2)


def test_reachable_free_matches_a_cell_by_cell_reckoning_on_random_maps():
    random = np.random.RandomState(7)
    for _ in range(40):
        height, width = random.randint(8, 40), random.randint(8, 40)
        cells = np.where(random.random_sample((height, width)) < random.choice([0.01, 0.03, 0.15]), 100, 0)
        cells = cells.astype(np.int8)
        cells[random.random_sample((height, width)) < 0.1] = -1
        grid = mapfile.Grid(width, height, RES, 0.0, 0.0, cells.tobytes())
        radius = random.choice([0.0, 0.1, 0.2, 0.34])
        standable = standable_by_hand(cells, radius)
        if not standable.any():
            continue
        rows, cols = np.nonzero(standable)
        pick = random.randint(rows.size)
        robot = ((cols[pick] + 0.5) * RES, (rows[pick] + 0.5) * RES)
        expected = bfs_labels(standable, 4)[0]
        expected = expected == expected[rows[pick], cols[pick]]
        np.testing.assert_array_equal(reachable_free(grid, robot, radius), expected)


def standable_by_hand(cells, radius):
    """Free cells whose centre is more than radius / RES + 0.5 cells from every occupied cell and
    from the ring of cells just beyond the canvas."""
    height, width = cells.shape
    walls = [(r, c) for r, c in zip(*np.nonzero(cells >= 50))]
    walls += [(r, c) for r in range(-1, height + 1) for c in (-1, width)]
    walls += [(r, c) for c in range(width) for r in (-1, height)]
    walls = np.array(walls)
    rows, cols = np.mgrid[0:height, 0:width]
    d2 = (rows[..., None] - walls[:, 0]) ** 2 + (cols[..., None] - walls[:, 1]) ** 2
    return (cells >= 0) & (cells < 50) & (d2.min(axis=2) > (radius / RES + 0.5) ** 2 + 1e-6)


def bfs_labels(mask, connectivity):
    """Connected components by breadth-first search, numbered in row-major order of first cells."""
    steps = [(-1, 0), (1, 0), (0, -1), (0, 1)]
    if connectivity == 8:
        steps += [(-1, -1), (-1, 1), (1, -1), (1, 1)]
    labels = np.zeros(mask.shape, dtype=np.int32)
    count = 0
    for start in zip(*np.nonzero(mask)):
        if labels[start]:
            continue
        count += 1
        labels[start] = count
        queue = deque([start])
        while queue:
            row, col = queue.popleft()
            for dr, dc in steps:
                r, c = row + dr, col + dc
                if 0 <= r < mask.shape[0] and 0 <= c < mask.shape[1] and mask[r, c] and not labels[r, c]:
                    labels[r, c] = count
                    queue.append((r, c))
    return labels, count


@pytest.mark.parametrize("connectivity", [4, 8])
def test_label_matches_a_breadth_first_search(connectivity):
    random = np.random.RandomState(24)
    shapes = [(1, 1), (1, 17), (17, 1), (2, 2), (5, 9), (23, 31), (40, 40)]
    for trial in range(150):
        shape = shapes[trial % len(shapes)]
        mask = random.random_sample(shape) < random.choice([0.1, 0.4, 0.55, 0.6, 0.8, 1.0])
        labels, count = label(mask, connectivity)
        expected, expected_count = bfs_labels(mask, connectivity)
        assert count == expected_count
        np.testing.assert_array_equal(labels, expected)
    assert label(np.zeros((3, 0), dtype=bool), 4)[1] == 0


def test_label_joins_a_long_snake_and_refuses_what_it_cannot_label():
    snake = np.zeros((41, 41), dtype=bool)
    snake[::2] = True
    snake[1::4, -1] = True
    snake[3::4, 0] = True
    labels, count = label(snake, 4)
    assert count == 1 and (labels[snake] == 1).all()
    with pytest.raises(ValueError):
        label(np.zeros(5, dtype=bool))
    with pytest.raises(ValueError):
        label(np.zeros((2, 2), dtype=bool), 6)
