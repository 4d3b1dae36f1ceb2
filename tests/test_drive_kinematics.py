"""Kinematics, duty mapping, ramping and odometry: properties over many inputs (hypothesis)."""

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from flask_move_server.config import DriveConfig
from flask_move_server.drive.kinematics import DutyMap, Limits, SkidSteer, desaturate
from flask_move_server.drive.motion import Motion
from flask_move_server.drive.odometry import ENCODERS, Odometry, ticks_per_metre

speeds = st.floats(-2.0, 2.0, allow_nan=False)
positive = st.floats(0.05, 2.0)
fractions = st.floats(0.0, 0.6)
# No per-example deadline: the machine is shared and loaded; speed is measured in bench/, not here.
relaxed = settings(deadline=None)


@relaxed
@given(speeds, speeds, positive, st.floats(0.5, 2.5))
def test_twist_to_wheels_and_back_is_the_identity(linear, angular, track, multiplier):
    base = SkidSteer(track, multiplier)
    back = base.body_velocity(*base.wheel_speeds(linear, angular))
    assert math.isclose(back[0], linear, abs_tol=1e-9) and math.isclose(back[1], angular, abs_tol=1e-9)


@relaxed
@given(positive, st.floats(0.5, 2.5))
def test_zero_velocity_gives_zero_wheel_speeds(track, multiplier):
    assert SkidSteer(track, multiplier).wheel_speeds(0.0, 0.0) == (0.0, 0.0)


@relaxed
@given(positive, st.floats(0.5, 2.5), st.floats(0.01, 2.0))
def test_a_larger_slip_multiplier_needs_faster_wheels_for_the_same_turn(track, multiplier, angular):
    plain = SkidSteer(track, 1.0).wheel_speeds(0.0, angular)
    slipping = SkidSteer(track, multiplier).wheel_speeds(0.0, angular)
    assert math.isclose(slipping[1], plain[1] * multiplier, rel_tol=1e-9)


@relaxed
@given(speeds, positive, fractions, st.floats(0.65, 1.0))
def test_duty_round_trips_to_the_speed_inside_the_range(speed, top, min_duty, max_duty):
    motor = DutyMap(top, min_duty, max_duty)
    expected = max(-top, min(top, speed))
    assert math.isclose(motor.speed(motor.duty(speed)), expected, rel_tol=1e-9, abs_tol=1e-9)


@relaxed
@given(speeds, positive, fractions, st.floats(0.65, 1.0))
def test_duty_never_exceeds_max_and_never_sits_in_the_deadband(speed, top, min_duty, max_duty):
    duty = DutyMap(top, min_duty, max_duty).duty(speed)
    assert abs(duty) <= max_duty + 1e-12
    assert duty == 0.0 or abs(duty) >= min_duty - 1e-12
    assert math.copysign(1, duty) == math.copysign(1, speed) or duty == 0.0


@relaxed
@given(positive, fractions, st.floats(0.65, 1.0))
def test_zero_speed_is_zero_duty_and_the_deadband_does_not_move(top, min_duty, max_duty):
    motor = DutyMap(top, min_duty, max_duty)
    assert motor.duty(0.0) == 0.0 and motor.duty(-0.0) == 0.0
    assert motor.speed(min_duty * 0.99) == 0.0 and motor.speed(-min_duty * 0.99) == 0.0


@relaxed
@given(speeds, speeds, positive)
def test_desaturation_keeps_the_arc_and_the_limit(left, right, limit):
    new_left, new_right = desaturate(left, right, limit)
    assert max(abs(new_left), abs(new_right)) <= limit + 1e-12
    assert math.isclose(new_left * right, new_right * left, abs_tol=1e-9)  # same ratio, same curve


@relaxed
@given(st.lists(st.tuples(speeds, speeds), min_size=1, max_size=30), st.floats(0.1, 3.0), st.floats(0.1, 6.0),
       st.floats(0.005, 0.1))
def test_ramping_never_exceeds_speed_or_acceleration_limits(targets, accel, angular_accel, dt):
    limits = Limits(0.4, 1.5, accel, angular_accel)
    velocity = (0.0, 0.0)
    for target in targets:
        new = limits.ramp(velocity, limits.clamp(*target), dt)
        assert abs(new[0]) <= 0.4 + 1e-12 and abs(new[1]) <= 1.5 + 1e-12
        assert abs(new[0] - velocity[0]) <= accel * dt + 1e-12
        assert abs(new[1] - velocity[1]) <= angular_accel * dt + 1e-12
        velocity = new


def drive(motion, odometry, linear, angular, seconds, dt):
    """Command (linear, angular) for ``seconds``, then zero until stopped, integrating open loop."""
    motion.command(linear, angular)
    for _ in range(int(round(seconds / dt))):
        motion.step(dt)
        odometry.advance(*motion.actual_velocity(), dt)
    motion.command(0.0, 0.0)
    while motion.velocity != (0.0, 0.0):
        motion.step(dt)
        odometry.advance(*motion.actual_velocity(), dt)


def square_motion():
    config = DriveConfig(max_linear_accel=0.5, max_angular_accel=2.0, min_duty=0.3, max_duty=0.9)
    return Motion.from_config(config)


def test_a_commanded_square_returns_to_the_start_within_a_millimetre():
    motion, odometry = square_motion(), Odometry()
    for _ in range(4):
        drive(motion, odometry, 0.2, 0.0, 1.0 / 0.2, dt=0.02)  # 1 m, ramps included
        drive(motion, odometry, 0.0, math.pi / 2 / 1.6, 1.6, dt=0.02)  # 90 degrees in 1.6 s
    assert math.hypot(odometry.x, odometry.y) < 0.001
    assert abs(odometry.yaw) < 0.01
    assert math.isclose(odometry.distance, 4.0, abs_tol=0.01)


def test_a_rounded_square_of_arcs_closes_even_with_coarse_steps():
    motion, odometry = square_motion(), Odometry()
    for _ in range(4):
        drive(motion, odometry, 0.2, 0.0, 2.0, dt=0.1)
        drive(motion, odometry, 0.2, math.pi / 2 / 3.0, 3.0, dt=0.1)  # a quarter circle
    assert math.hypot(odometry.x, odometry.y) < 0.001


def test_encoder_odometry_from_scripted_ticks():
    per_metre = ticks_per_metre(1920, 0.0325)
    track = 0.2
    odometry = Odometry(ENCODERS)
    previous = (0, 0)
    script = [(i * 94, i * 94) for i in range(1, 11)]  # straight ahead
    spin = int(round(math.pi / 2 * track / 2 * per_metre))
    script += [(script[-1][0] - spin, script[-1][1] + spin)]  # quarter turn on the spot
    for ticks in script:
        left, right = ((t - p) / per_metre for t, p in zip(ticks, previous))
        odometry.advance_wheels(left, right, track, 0.05)
        previous = ticks
    assert math.isclose(odometry.x, 940 / per_metre, rel_tol=1e-9) and abs(odometry.y) < 1e-9
    assert math.isclose(odometry.yaw, math.pi / 2, abs_tol=2 * (1 / per_metre) / track)


@settings(max_examples=50, deadline=None)
@given(st.floats(0.0, 10.0))
def test_covariance_grows_with_distance_and_is_larger_open_loop(metres):
    closed, open_loop = Odometry(ENCODERS), Odometry()
    closed.distance = open_loop.distance = metres
    assert closed.pose_covariance()[0] <= open_loop.pose_covariance()[0]
    assert open_loop.twist_covariance()[0] > closed.twist_covariance()[0]
    near = Odometry()
    assert near.pose_covariance()[0] <= open_loop.pose_covariance()[0]
