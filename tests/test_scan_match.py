"""The scan-match score tells a right pose from a wrong one: the demo flat's map, scans cast by the
sim's own laser (tests/test_sim_*.py run the same laser as the robot's /scan) from the true pose.

A score that believed the covariance would pass both; the laser's end points on the map's walls
do not: 0.3 m or 10° off and most of them land in free space.
"""

import math
import os
from types import SimpleNamespace

import pytest

from flask_move_server.core.geometry import Pose2D
from flask_move_server.diagnostics import checks
from flask_move_server.diagnostics.scan_match import match_share
from flask_move_server.maps import mapfile
from flask_move_server.sim.laser import Laser
from tests.conftest import ROOT

GRID = mapfile.load(os.path.join(ROOT, "config", "maps", "demo.yaml"))
BASE = Pose2D(0.0, 0.0, 0.0)  # the laser at base_link's origin, as the sim's scans are cast


def scan_from(pose):
    laser = Laser(GRID)
    return SimpleNamespace(ranges=laser.scan(pose), angle_min=laser.angle_min, angle_increment=laser.angle_increment,
                           range_min=laser.range_min, range_max=laser.range_max)


@pytest.mark.parametrize("truth", [Pose2D(0.0, 0.0, 0.0), Pose2D(8.4, 0.9, 0.0), Pose2D(-0.8, 4.3, 1.57),
                                   Pose2D(6.2, 4.5, 3.0)])
def test_a_right_pose_scores_high_and_one_off_by_0_3_m_or_10_degrees_low(truth):
    scan = scan_from(truth)
    right, points = match_share(GRID, truth, BASE, scan)
    assert points >= 100 and right >= 0.9
    for wrong in (Pose2D(truth.x + 0.3, truth.y, truth.yaw), Pose2D(truth.x, truth.y - 0.3, truth.yaw),
                  Pose2D(truth.x, truth.y, truth.yaw + math.radians(10))):
        share, _ = match_share(GRID, wrong, BASE, scan)
        assert share < checks.SCAN_MATCH_WARN < right, (wrong, share)


def test_the_laser_mounted_half_a_turn_round_is_taken_into_account():
    """The A1 mounted motor-back (yaw pi in base_link, as on the robot): its own frame's scan matches
    only with its mount in the sum."""
    truth = Pose2D(2.0, 1.0, 0.5)
    ranges = scan_from(truth).ranges
    half = len(ranges) // 2
    in_laser_frame = SimpleNamespace(**dict(vars(scan_from(truth)), ranges=ranges[half:] + ranges[:half]))
    assert match_share(GRID, truth, Pose2D(0.0, 0.0, math.pi), in_laser_frame)[0] >= 0.9
    assert match_share(GRID, truth, BASE, in_laser_frame)[0] < checks.SCAN_MATCH_WARN


def test_too_few_points_tell_nothing():
    scan = SimpleNamespace(ranges=[math.inf] * 350 + [1.0] * 10, angle_min=-math.pi,
                           angle_increment=2 * math.pi / 360, range_min=0.15, range_max=8.0)
    assert match_share(GRID, Pose2D(0.0, 0.0, 0.0), BASE, scan) == (None, 10)
