"""``dock/approach.py`` and the simulated charger's contacts: the last 40 cm onto the charger.

The approach is driven here as the sim's body drives it (``along_arc`` at each step's velocity),
from where move_base leaves a robot at the staging pose (its shipped goal tolerance: 12 cm, 0.2
rad): it must come onto the charger's contacts as strictly as the simulated charger asks
(``sim/battery.py`` ``on_contacts``), and a robot whose localization is off sideways must miss.
"""

import math

import pytest

from flask_move_server.core.geometry import Pose2D, along_arc, compose
from flask_move_server.dock.approach import Approach, offset, staging_pose, within
from flask_move_server.sim.battery import on_contacts

DOCK = Pose2D(1.0, 2.0, math.pi / 2)  # facing the charger, north
STAGING = 0.4
PERIOD = 0.1


RIGHT = Pose2D(0.0, 0.0, 0.0)


def drive_on(true, belief_error=RIGHT, speed=0.05, steps=400):
    """Approach from ``true`` with localization off by ``belief_error`` (in the robot's frame): the true end pose."""
    approach = Approach(DOCK, speed)
    for _ in range(steps):
        step = approach.step(compose(true, belief_error))
        if step is None:
            return true
        linear, angular = step
        true = along_arc(true, linear * PERIOD, angular * PERIOD)
    raise AssertionError("the approach never ended")


def test_the_staging_pose_lies_behind_the_dock_facing_it():
    staging = staging_pose(DOCK, STAGING)
    assert (staging.x, staging.y, staging.yaw) == pytest.approx((1.0, 1.6, DOCK.yaw))
    off = offset(DOCK, staging)
    assert off.along == pytest.approx(-STAGING) and off.beside == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("beside,yaw", [(0.0, 0.0), (0.12, 0.0), (-0.12, 0.2), (0.08, -0.2), (-0.05, 0.35)])
def test_from_anywhere_move_base_leaves_it_the_approach_touches_the_contacts(beside, yaw):
    start = compose(staging_pose(DOCK, STAGING), Pose2D(0.0, beside, yaw))
    end = drive_on(start)
    assert on_contacts(DOCK, end), offset(DOCK, end)
    assert within(DOCK, end)


def test_a_belief_eight_centimetres_off_sideways_drives_beside_the_contacts_and_misses():
    end = drive_on(staging_pose(DOCK, STAGING), belief_error=Pose2D(0.0, 0.08, 0.0))
    off = offset(DOCK, end)
    assert not on_contacts(DOCK, end) and abs(off.beside) == pytest.approx(0.08, abs=0.01)
    assert within(DOCK, compose(end, Pose2D(0.0, 0.08, 0.0)))  # where it believes it is: on the dock


def test_the_contacts_want_it_touching_straight_and_centred():
    assert on_contacts(DOCK, DOCK)
    for error in (Pose2D(-0.05, 0.0, 0.0), Pose2D(0.0, 0.05, 0.0), Pose2D(0.0, 0.0, 0.12), Pose2D(0.07, 0.0, 0.0)):
        assert not on_contacts(DOCK, compose(DOCK, error)), error
