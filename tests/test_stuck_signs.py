"""The signs of a stuck robot, from what the robot observes: scans of the demo flat cast by the sim's own
laser (the one behind the demo's /scan), the shipped footprint, the demo map. Pure: no ROS.

A robot whose wheels turn against a door jamb claims motion in its odometry that the laser does not
see; one that really drives changes its scan as the odometry says; a long corridor, which looks the
same either way, must not be called stuck. The footprint touches what lies on it, and a straight
back-out has the room the laser shows behind, not less because of a wall alongside.
"""

import math
import os

import pytest

from flask_move_server.core.geometry import Pose2D, compose, inverse
from flask_move_server.maps import mapfile
from flask_move_server.recovery import footprint, relocate, words
from flask_move_server.recovery.back_out import BLOCKED, DONE, NO_ROOM, TIMEOUT, BackOut, ended
from flask_move_server.recovery.detector import MotionWatch, QuickAborts
from flask_move_server.recovery.scan_motion import MOVED, STILL, end_points, verdict
from flask_move_server.sim.laser import Laser
from flask_move_server.sim.occupancy import OccupancyMap
from tests.conftest import ROOT

GRID = mapfile.load(os.path.join(ROOT, "config", "maps", "demo.yaml"))
LASER = Laser(GRID)
BASE = Pose2D(0.0, 0.0, 0.0)
FOOTPRINT = footprint.read(os.path.join(ROOT, "config"))  # the shipped costmap_common.yaml's, padded


def points_at(pose, laser=LASER):
    """The end points (robot frame) of a scan cast from ``pose`` on the world of ``laser``."""
    return end_points(laser.scan(pose), laser.angle_min, laser.angle_increment, laser.range_min, laser.range_max,
                      BASE)


def motion(a, b):
    return compose(inverse(a), b)


# did it move as the odometry says? -------------------------------------------------------------

@pytest.mark.parametrize("start, claimed", [
    (Pose2D(0.0, 0.0, 0.0), Pose2D(0.15, 0.0, 0.0)),      # the living room, straight on
    (Pose2D(0.22, 2.3, 1.5), Pose2D(-0.2, 0.02, 0.05)),    # against the office door's jamb, backing off it
    (Pose2D(6.2, 4.5, 3.0), Pose2D(0.0, 0.0, 0.4)),        # turning in the bedroom
])
def test_odometry_the_laser_does_not_see_is_still_and_odometry_it_sees_is_moved(start, claimed):
    before = points_at(start)
    assert verdict(before, points_at(start), claimed) == STILL  # the wheels turned, the robot did not
    assert verdict(before, points_at(compose(start, claimed)), claimed) == MOVED


def test_a_long_corridor_driven_along_is_never_called_still():
    """Walls either side and nothing in range ahead or behind: both hypotheses explain the scan."""
    width, height, res = 400, 30, 0.05  # 20 m x 1.5 m
    cells = [0] * (width * height)
    for col in range(width):
        cells[col] = cells[(height - 1) * width + col] = 100
    corridor = Laser(OccupancyMap(width, height, res, 0.0, 0.0, cells), range_max=4.0)
    start = Pose2D(10.0, 0.75, 0.0)
    for moved in (False, True):
        after = points_at(compose(start, Pose2D(0.15, 0.0, 0.0)) if moved else start, corridor)
        assert verdict(points_at(start, corridor), after, Pose2D(0.15, 0.0, 0.0)) != STILL


def test_too_little_odometry_or_too_few_points_tell_nothing():
    here = points_at(Pose2D(0.0, 0.0, 0.0))
    assert verdict(here, here, Pose2D(0.05, 0.0, 0.1)) is None
    assert verdict(here[:10], here[:10], Pose2D(0.3, 0.0, 0.0)) is None


def test_the_motion_watch_says_blocked_after_two_still_comparisons_and_forgets_on_motion():
    watch, truth, odometry = MotionWatch(), Pose2D(0.22, 2.3, 1.5), Pose2D(0.0, 0.0, 0.0)
    assert not watch.scan(points_at(truth), odometry)
    step = Pose2D(0.12, 0.0, 0.0)
    odometry = compose(odometry, step)
    assert not watch.scan(points_at(truth), odometry)  # one "still": not yet
    truth, odometry = compose(truth, Pose2D(-0.12, 0.0, 0.0)), compose(odometry, Pose2D(-0.12, 0.0, 0.0))
    assert not watch.scan(points_at(truth), odometry) and watch.moving  # it did move: counted afresh
    for _ in range(2):
        odometry = compose(odometry, step)
        blocked = watch.scan(points_at(truth), odometry)
    assert blocked


def test_a_robot_standing_still_keeps_comparing_with_its_newest_scan():
    watch, truth = MotionWatch(), Pose2D(0.0, 0.0, 0.0)
    for _ in range(5):
        assert not watch.scan(points_at(truth), Pose2D(0.0, 0.0, 0.0))
    assert watch.last is None


# the footprint -------------------------------------------------------------------------------------

def test_the_shipped_footprint_is_padded_as_costmap_2d_pads_it():
    expected = sorted([(0.15, 0.135), (0.15, -0.135), (-0.15, -0.135), (-0.15, 0.135)])
    assert [pytest.approx(p) for p in sorted(FOOTPRINT)] == expected
    assert footprint.inscribed_radius(FOOTPRINT) == pytest.approx(0.135)
    assert footprint.circumscribed_radius(FOOTPRINT) == pytest.approx(math.hypot(0.15, 0.135))


def test_what_lies_on_the_footprint_touches_it_and_what_lies_beside_does_not():
    assert footprint.touching([(0.16, 0.0), (0.0, 0.5)], FOOTPRINT, 0.03) == [(0.16, 0.0)]
    assert footprint.touching([(0.2, 0.0), (-0.19, 0.1)], FOOTPRINT, 0.03) == []


def test_the_room_behind_is_what_the_laser_shows_there_not_a_wall_alongside():
    alongside = [(x / 10.0, 0.15) for x in range(-10, 10)]  # a wall 1.5 cm from the robot's side
    assert footprint.room_along(alongside, FOOTPRINT, 0.35, 0.05) == pytest.approx(0.35)
    behind = alongside + [(-0.55, 0.0)]
    assert footprint.room_along(behind, FOOTPRINT, 0.35, 0.05) == pytest.approx(0.35)  # 0.4 m clear, 0.35 asked
    assert footprint.room_along(behind + [(-0.3, 0.1)], FOOTPRINT, 0.35, 0.05) == pytest.approx(0.1)
    assert footprint.room_along([(-0.17, -0.05)], FOOTPRINT, 0.35, 0.05) == 0.0
    assert footprint.room_along([(0.3, 0.0)], FOOTPRINT, 0.35, 0.05) == pytest.approx(0.35)  # ahead: no matter


def test_on_the_map_at_a_pose_slid_into_the_jamb_and_not_in_the_doorway():
    assert footprint.on_the_map(GRID, Pose2D(0.3, 2.38, 1.57), FOOTPRINT)  # the odometry pushed it into the wall
    assert footprint.on_the_map(GRID, Pose2D(0.2, 2.33, 0.0), FOOTPRINT)   # within the inscribed radius of it
    assert not footprint.on_the_map(GRID, Pose2D(0.75, 2.5, 1.57), FOOTPRINT)  # the middle of the door
    assert not footprint.on_the_map(GRID, Pose2D(0.0, 0.0, 0.0), FOOTPRINT)  # the dock


# goals that fail at once, the back-out, the words ----------------------------------------------------

def test_quick_aborts_without_moving_count_in_a_row_and_anything_else_breaks_the_row():
    aborts = QuickAborts(quick=20.0)
    assert not aborts.ended("aborted", 4.8, 0.0)
    assert aborts.ended("aborted", 4.9, 0.02)
    aborts.reset()
    assert not aborts.ended("aborted", 4.8, 0.0)
    assert not aborts.ended("aborted", 25.0, 0.0)  # slow: move_base tried for a while
    assert not aborts.ended("aborted", 4.8, 0.0)
    assert not aborts.ended("aborted", 4.8, 0.5)   # it moved
    assert not aborts.ended("aborted", 4.8, None)  # not known: counts for nothing
    assert not aborts.ended("aborted", 4.8, 0.0) and aborts.in_a_row == 1
    assert not aborts.ended("canceled", 1.0, 0.0) and aborts.in_a_row == 1  # the owner's cancel says nothing
    assert aborts.ended("aborted", 3.0, 0.0)


def test_a_back_out_goes_back_slowly_until_far_enough_or_stopped_by_what_it_sees():
    back = BackOut(0.3, 0.1)
    assert back.next(0.0, 0.0, 0.3, False) == -0.1
    assert back.next(2.0, 0.3, 0.1, False) == DONE
    assert back.next(1.0, 0.05, 0.0, False) == NO_ROOM
    assert back.next(1.5, 0.15, 0.0, False) == DONE  # cut short, but off what it touched
    assert back.next(1.0, 0.05, 0.2, True) == BLOCKED
    assert back.next(back.allowed + 0.1, 0.02, 0.2, False) == TIMEOUT
    assert back.next(0.5, 0.0, None, False) == NO_ROOM  # no fresh scan: no room it can be sure of
    assert ended(DONE) and not ended(-0.1)


def test_the_words_say_where_in_the_owner_s_names_first():
    places = [("office", -0.8, 4.3), ("sofa", -0.5, 1.0)]
    assert words.place(Pose2D(0.22, 2.3, 0.0), places) == "near sofa"
    assert words.place(Pose2D(8.0, 5.0, 0.0), places) == "at x 8.0, y 5.0"
    assert words.place(None, places) is None
    assert words.backing_out("near sofa", 0.3).startswith("Stuck near sofa: backing out 30 cm")
    assert words.no_room("near sofa").startswith("Stuck near sofa: drive it out with the joystick")


# putting the position back --------------------------------------------------------------------------

def test_a_position_slid_with_the_odometry_is_put_back_where_the_laser_fits_the_map():
    truth = Pose2D(0.2, 2.3, 1.55)  # pressed on the office door's jamb
    slip = Pose2D(0.3, 0.0, 0.0)  # the odometry counted 0.3 m more straight on
    for took in (1.0, 0.6, 1.3):  # AMCL took all of it, some of it, more (the real one: 0.36 of 0.3 m)
        estimate = compose(truth, Pose2D(slip.x * took, 0.0, 0.0))
        pose, before, after = relocate.put_back(GRID, estimate, slip, points_at(truth))
        assert math.hypot(pose.x - truth.x, pose.y - truth.y) < 0.04, (took, pose)
        assert after >= 0.9 > before + relocate.BETTER


def test_a_position_that_did_not_slide_is_left_alone():
    truth = Pose2D(0.2, 2.3, 1.55)
    assert relocate.put_back(GRID, truth, Pose2D(0.3, 0.0, 0.0), points_at(truth)) is None
    assert not relocate.slipped(Pose2D(0.03, 0.0, 0.02)) and relocate.slipped(Pose2D(0.0, 0.0, 0.2))
