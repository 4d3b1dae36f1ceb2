"""``sim/belief.py``: what the simulated AMCL believes after a pose estimate, beside the truth."""

import math

from flask_move_server.core.geometry import Pose2D, along_arc
from flask_move_server.sim.belief import Belief

SIGMA_XY, SIGMA_YAW = 0.5, math.pi / 12  # RViz's 2D Pose Estimate, as the server sends it


def drive(belief, true, metres, step=0.05):
    """Drive ``metres`` straight ahead from ``true`` in small steps; the truth at the end."""
    for _ in range(int(round(metres / step))):
        true = along_arc(true, step, 0.0)
        belief.moved(true)
    return true


def apart(a, b):
    return math.hypot(a.x - b.x, a.y - b.y)


def test_an_estimate_far_from_the_truth_is_kept_and_moves_with_the_robot():
    belief, kitchen = Belief(), Pose2D(8.4, 0.9, 0.0)
    assert belief.estimate(Pose2D(0.0, 0.0, 0.0), kitchen, SIGMA_XY, SIGMA_YAW) is False
    assert apart(belief.of(kitchen), Pose2D(0.0, 0.0, 0.0)) < 1e-9
    true = drive(belief, kitchen, 2.0)
    believed = belief.of(true)  # two metres on from the dock, as the odometry says: never the truth
    assert apart(believed, Pose2D(2.0, 0.0, 0.0)) < 1e-6 and apart(true, Pose2D(10.4, 0.9, 0.0)) < 1e-6


def test_an_estimate_near_the_truth_converges_as_the_robot_moves_not_at_rest():
    belief, true = Belief(), Pose2D(1.0, 1.0, 0.3)
    assert belief.estimate(Pose2D(1.4, 0.8, 0.5), true, SIGMA_XY, SIGMA_YAW) is True
    belief.moved(true)  # no motion: no update
    assert apart(belief.of(true), Pose2D(1.4, 0.8, 0.0)) < 1e-9
    true = drive(belief, true, 1.5)
    assert apart(belief.of(true), true) < 0.01
    assert abs(belief.of(true).yaw - true.yaw) < 0.01


def test_a_yaw_far_off_is_not_converged_even_close_by():
    belief, true = Belief(), Pose2D(1.0, 1.0, 0.0)
    assert belief.estimate(Pose2D(1.0, 1.0, math.pi / 2), true, SIGMA_XY, SIGMA_YAW) is False
    true = drive(belief, true, 1.0)
    assert abs(belief.of(true).yaw - math.pi / 2) < 1e-6
