"""The simulated SLAM: a map grown from scans of the true world, and planning on it through the unknown."""

import math
import os
from array import array

import pytest

from flask_move_server.core.errors import PlanningFailed
from flask_move_server.core.geometry import Pose2D
from flask_move_server.sim import occupancy
from flask_move_server.sim.body import RobotBody
from flask_move_server.sim.costmap import Costmap
from flask_move_server.sim.follower import DONE, FollowerLimits, PathFollower
from flask_move_server.sim.laser import Laser
from flask_move_server.sim.planner import path_length
from flask_move_server.sim.slam import GrowingMapPlanner, SlamMap
from tests.conftest import ROOT

DEMO_MAP = os.path.join(ROOT, "config", "maps", "demo.yaml")
DOCK = Pose2D(0.0, 0.0, 0.0)
OCCUPIED = 100


@pytest.fixture(scope="module")
def truth():
    return occupancy.load(DEMO_MAP)


def mapped_from(truth, *poses, **laser_args):
    slam = SlamMap.around(Laser(truth, **laser_args), margin=1.0)
    for pose in poses:
        slam.integrate(pose)
    return slam


def known_cells(slam, truth):
    """(SLAM value, true value) of every true-map cell the SLAM map knows."""
    pairs = []
    for row in range(truth.height):
        for col in range(truth.width):
            x, y = truth.center_of(col, row)
            seen = slam.value_at(x, y)
            if seen != -1:
                pairs.append((seen, truth.cells[row * truth.width + col]))
    return pairs


def test_the_robot_starts_knowing_nothing(truth):
    slam = mapped_from(truth)
    assert set(slam.grid_bytes()) == {0xFF}
    assert slam.value_at(0.0, 0.0) == -1 and slam.version == 0


def test_what_the_laser_saw_is_mapped_as_it_truly_is(truth):
    slam = mapped_from(truth, DOCK, Pose2D(1.5, 1.0, 1.0), Pose2D(2.5, -0.5, 2.0))
    pairs = known_cells(slam, truth)
    assert len(pairs) > 2000
    assert all((seen, true) in ((0, 0), (100, 100)) for seen, true in pairs)
    assert slam.value_at(0.5, 0.5) == 0            # the living room floor
    assert slam.value_at(3.97, 2.0) == 100         # the living room's wall to the kitchen
    assert slam.value_at(-2.4, 0.0) == -1          # beyond the outer wall


def test_nothing_is_seen_through_a_wall(truth):
    slam = mapped_from(truth, DOCK, Pose2D(6.5, 1.2, 0.0), Pose2D(4.6, 0.0, -1.5))
    assert slam.value_at(4.6, -1.5) == -1          # inside the store room, which has no door
    assert slam.value_at(6.0, 4.5) == -1           # the bedroom, behind the kitchen's wall
    assert slam.value_at(4.6, -0.98) == 100        # the store room's wall, seen from the kitchen


def test_a_beam_without_echo_marks_free_only(truth):
    slam = mapped_from(truth, DOCK, range_max=1.0)
    assert slam.value_at(0.9, 0.0) == 0 and slam.value_at(1.2, 0.0) == -1
    assert OCCUPIED not in set(slam.grid_bytes())



def test_the_version_changes_only_when_the_map_does(truth):
    slam = mapped_from(truth)
    assert slam.integrate(DOCK) > 0 and slam.version == 1
    assert slam.integrate(DOCK) == 0 and slam.version == 1      # same view: more certain, same map
    assert slam.integrate(Pose2D(2.0, 1.5, 0.0)) > 0 and slam.version == 2
    assert slam.scans == 3


def test_the_grid_bytes_are_the_cells_bottom_row_first(truth):
    slam = mapped_from(truth, DOCK)
    data = slam.grid_bytes()
    assert len(data) == slam.width * slam.height
    values = array("b", data)
    for row in range(0, slam.height, 7):
        for col in range(0, slam.width, 3):
            x = slam.origin_x + (col + 0.5) * slam.resolution
            y = slam.origin_y + (row + 0.5) * slam.resolution
            assert values[row * slam.width + col] == slam.value_at(x, y)
    snapshot = slam.occupancy_map()
    assert snapshot.cells == list(values) and snapshot.value_at(0.5, 0.5) == 0


def test_the_canvas_may_be_larger_than_the_world_but_aligned_to_its_cells(truth):
    laser = Laser(truth)
    big = SlamMap(laser, 600, 500, truth.origin_x - 5.0, truth.origin_y - 5.0)
    big.integrate(DOCK)
    assert big.value_at(0.5, 0.5) == 0 and big.value_at(3.97, 2.0) == 100
    with pytest.raises(ValueError):
        SlamMap(laser, 600, 500, truth.origin_x - 0.01, truth.origin_y)


def test_the_laser_traces_the_cells_it_scans_through(truth):
    laser = Laser(truth)
    crossed = []
    beams = laser.trace(DOCK, crossed.append)
    for (r, hit), scanned in zip(beams, laser.scan(DOCK)):
        assert (hit is None) == math.isinf(scanned)
        if hit is not None:
            assert r == pytest.approx(scanned) and truth.cells[hit] == 100
    assert crossed and all(truth.cells[p] == 0 for p in crossed)


# planning on the growing map -------------------------------------------------------------

def hall_with_a_wall():
    """A 5 x 3 m room, a wall across it at x 2.5 with a gap at the top (y 2.2 .. 3)."""
    res, width, height = 0.05, 100, 60
    cells = [0] * (width * height)
    for row in range(height):
        for col in range(width):
            edge = col in (0, width - 1) or row in (0, height - 1)
            wall = col in (50, 51) and row < 44
            if edge or wall:
                cells[row * width + col] = 100
    return occupancy.OccupancyMap(width, height, res, 0.0, 0.0, cells, "hall")


def test_a_goal_in_unknown_space_is_planned_through_the_unknown(truth):
    slam = mapped_from(truth, DOCK)
    planner = GrowingMapPlanner(slam, 0.15, 0.1)
    assert slam.value_at(6.0, 4.5) == -1
    path = planner.plan((0.0, 0.0), (6.0, 4.5))     # into the bedroom nobody has seen
    assert path[0] == (0.0, 0.0) and path[-1] == (6.0, 4.5)
    on_the_way = [(a[0] + (b[0] - a[0]) * k / 20, a[1] + (b[1] - a[1]) * k / 20)
                  for a, b in zip(path, path[1:]) for k in range(20)]
    assert any(slam.value_at(x, y) == -1 for x, y in on_the_way[:-20])   # not only the goal is unknown
    assert not planner.path_blocked(path)


def test_a_wall_found_later_blocks_the_straight_way():
    slam = SlamMap.around(Laser(hall_with_a_wall()), margin=0.5)
    planner = GrowingMapPlanner(slam, 0.15, 0.05)
    before = planner.plan((1.0, 1.0), (4.0, 1.0))
    assert path_length(before) == pytest.approx(3.0, abs=0.05)   # straight through the unknown
    slam.integrate(Pose2D(1.0, 1.0, 0.0))
    after = planner.plan((1.0, 1.0), (4.0, 1.0))
    assert path_length(after) > 4.0                                # round the wall, through the gap
    assert all(p[1] > 1.8 for p in after[1:-1])
    assert planner.path_blocked(before) and not planner.path_blocked(after)
    assert planner.rebuilds == 2
    planner.plan((1.0, 1.0), (4.0, 1.5))
    assert planner.rebuilds == 2                                   # map unchanged: costmap kept


def test_a_goal_on_a_wall_seen_is_refused():
    slam = SlamMap.around(Laser(hall_with_a_wall()), margin=0.5)
    slam.integrate(Pose2D(1.0, 1.0, 0.0))
    with pytest.raises(PlanningFailed) as info:
        GrowingMapPlanner(slam, 0.15).plan((1.0, 1.0), (2.55, 1.0))
    assert info.value.reason == "occupied"


def drive_exploring(truth, goal, seconds=120.0, dt=0.1, scan_every=10):
    """Drive from the dock to ``goal`` knowing nothing, mapping as it goes (a scan per simulated second,
    to keep the test fast) and replanning when a wall found since blocks the path, as the move_base
    stand-in will in mapping mode; (final pose, map, replans)."""
    body = RobotBody(Costmap(truth, 0.15), track=0.2)
    slam = SlamMap.around(Laser(truth), margin=1.0)
    planner = GrowingMapPlanner(slam, 0.15, 0.1)
    slam.integrate(body.pose)
    path = planner.plan((0.0, 0.0), goal)
    follower = PathFollower(path, 0.0, FollowerLimits())
    replans = 0
    for step in range(int(seconds / dt)):
        pose = body.pose
        if step % scan_every == 0 and slam.integrate(pose) and planner.path_blocked([(pose.x, pose.y)] + path[1:]):
            path = planner.plan((pose.x, pose.y), goal)
            follower = PathFollower(path, 0.0, FollowerLimits())
            replans += 1
        if follower.state == DONE and follower.reached(pose):
            return pose, slam, replans
        v, w = follower.command(pose)
        body.step(v - w * 0.1, v + w * 0.1, dt)
    return body.pose, slam, replans


def test_a_goal_into_unknown_space_is_reached_by_replanning_around_the_walls_found(truth):
    pose, slam, replans = drive_exploring(truth, (6.2, 4.5))     # the bedroom, behind two walls from the dock
    assert pose.distance_to(Pose2D(6.2, 4.5, 0.0)) < 0.15
    assert replans >= 1
    assert slam.value_at(5.45, 2.5) == 0                  # through the bedroom door it found
