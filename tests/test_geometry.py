"""Planar maths (geometry.py): clamping, the arc a base drives, and tf-style pose algebra (hypothesis)."""

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from flask_move_server.core.geometry import (
    Pose2D,
    along_arc,
    clamp,
    compose,
    interpolate,
    inverse,
    normalize_angle,
    quaternion_to_yaw,
    yaw_to_quaternion,
)

coordinates = st.floats(-20.0, 20.0)
headings = st.floats(-math.pi, math.pi)
poses = st.builds(Pose2D, coordinates, coordinates, headings)
distances = st.floats(-2.0, 2.0)
turns = st.floats(-4.0, 4.0)
ORIGIN = Pose2D(0.0, 0.0, 0.0)
# No per-example deadline: the machine is shared and loaded; speed is measured in bench/, not here.
relaxed = settings(deadline=None)


def near(a, b, tol=1e-6):
    """Same place and same heading (headings compared round the circle)."""
    return math.hypot(a.x - b.x, a.y - b.y) <= tol and abs(normalize_angle(a.yaw - b.yaw)) <= tol


def small_steps(pose, distance, turn, steps):
    """``along_arc`` done the naive way: many tiny straight moves, each followed by a tiny turn."""
    x, y, yaw = pose.x, pose.y, pose.yaw
    ds, dth = distance / steps, turn / steps
    for _ in range(steps):
        x, y, yaw = x + ds * math.cos(yaw), y + ds * math.sin(yaw), yaw + dth
    return Pose2D(x, y, yaw)


@given(st.floats(-1e3, 1e3), st.floats(0.0, 1e3))
def test_clamp_keeps_a_speed_within_the_limit_and_leaves_allowed_speeds_alone(value, limit):
    held = clamp(value, limit)
    assert -limit <= held <= limit
    assert held == value or abs(held) == limit
    assert clamp(held, limit) == held


@relaxed
@given(poses, distances, turns)
def test_the_arc_is_where_many_small_steps_end(pose, distance, turn):
    # Euler's error over n steps is about |distance * turn| / (2 n): allow twice that.
    tol = abs(distance * turn) / 20000 + 1e-9
    assert near(along_arc(pose, distance, turn), small_steps(pose, distance, turn, steps=20000), tol=tol)


@relaxed
@given(poses, distances, turns, st.integers(2, 20))
def test_the_arc_does_not_depend_on_the_step_size(pose, distance, turn, steps):
    cut = pose
    for _ in range(steps):
        cut = along_arc(cut, distance / steps, turn / steps)
    assert near(along_arc(pose, distance, turn), cut)


def test_a_half_circle_ends_two_radii_to_the_side():
    end = along_arc(ORIGIN, math.pi, math.pi)  # radius 1 m
    assert math.isclose(end.x, 0.0, abs_tol=1e-9) and math.isclose(end.y, 2.0, abs_tol=1e-9)
    assert math.isclose(abs(end.yaw), math.pi, abs_tol=1e-9)


@given(poses, distances)
def test_the_straight_line_formula_and_the_arc_agree_where_they_meet(pose, distance):
    """Below a turn of 1e-6 rad the midpoint formula takes over: no jump at the switch."""
    assert near(along_arc(pose, distance, 0.999e-6), along_arc(pose, distance, 1.001e-6), tol=1e-8)


@given(poses, distances, turns)
def test_an_arc_is_the_same_arc_in_the_robots_own_frame(pose, distance, turn):
    assert near(along_arc(pose, distance, turn), compose(pose, along_arc(ORIGIN, distance, turn)))


@given(poses)
def test_a_pose_composed_with_its_inverse_is_the_identity(a):
    assert near(compose(a, inverse(a)), ORIGIN)
    assert near(compose(inverse(a), a), ORIGIN)
    assert near(inverse(inverse(a)), a)


@given(poses, poses, poses)
def test_composition_round_trips_and_associates(a, b, c):
    assert near(compose(inverse(a), compose(a, b)), b, tol=1e-9)
    assert near(compose(compose(a, b), c), compose(a, compose(b, c)), tol=1e-6)


def test_the_map_to_odom_correction_puts_odometry_on_the_true_pose():
    """What an AMCL publishes: map → odom = true ∘ odom⁻¹, so map → odom → base_link is the true pose."""
    true, odom = Pose2D(1.0, 2.0, 0.5), Pose2D(-0.3, 0.4, -1.0)
    assert near(compose(compose(true, inverse(odom)), odom), true, tol=1e-12)


@given(poses, poses)
def test_interpolation_runs_from_one_pose_to_the_other(a, b):
    assert near(interpolate(a, b, 0.0), a)
    assert near(interpolate(a, b, 1.0), b)
    half = interpolate(a, b, 0.5)
    assert math.isclose(half.x, (a.x + b.x) / 2, abs_tol=1e-9)
    assert abs(normalize_angle(half.yaw - a.yaw)) <= math.pi / 2 + 1e-9  # never the long way round


def test_interpolation_turns_the_short_way_across_pi():
    half = interpolate(Pose2D(0, 0, 3.0), Pose2D(0, 0, -3.0), 0.5)
    assert math.isclose(abs(half.yaw), math.pi, abs_tol=1e-9)


@given(st.floats(-20.0, 20.0))
def test_a_yaw_survives_the_quaternion_round_trip_wrapped_to_a_half_open_circle(yaw):
    back = quaternion_to_yaw(*yaw_to_quaternion(yaw))
    assert -math.pi <= back <= math.pi
    assert abs(normalize_angle(back - yaw)) < 1e-9
    assert math.isclose(math.hypot(*yaw_to_quaternion(yaw)), 1.0)
