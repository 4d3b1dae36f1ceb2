"""The simulated world's clock: a loaded machine slows the sim and its move_base watchdogs alike."""

import pytest

from flask_move_server.core.geometry import Pose2D
from flask_move_server.sim.clock import SimClock, overload_text
from flask_move_server.sim.watches import ProgressWatch


class FakeTime:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def run(clock, real, gaps):
    """Tick ``clock`` after each real gap (s), moving the fake real time along."""
    for gap in gaps:
        real.now += gap
        clock.tick(gap)


def test_a_world_on_time_keeps_real_time_times_the_speed_factor():
    real = FakeTime()
    clock = SimClock(50.0, speed_factor=4.0, clock=real)
    run(clock, real, [0.02] * 50)
    assert clock.now() == pytest.approx(4.0)
    assert clock.report() == pytest.approx((50.0, 1.0))


def test_late_ticks_lose_the_time_beyond_two_periods():
    real = FakeTime()
    clock = SimClock(50.0, clock=real)
    run(clock, real, [0.5] * 10)  # 5 s of real time, the world starved: 2 Hz
    assert clock.now() == pytest.approx(0.4)
    achieved, share = clock.report()
    assert (achieved, share) == pytest.approx((2.0, 0.08))
    assert overload_text(achieved, 50, share) == \
        "the sim ran at 2 Hz instead of 50 (0.08 of real time): machine overloaded"


def test_the_report_restarts_with_each_look():
    real = FakeTime()
    clock = SimClock(50.0, clock=real)
    run(clock, real, [0.5] * 10)
    clock.report()
    run(clock, real, [0.02] * 50)
    assert clock.report() == pytest.approx((50.0, 1.0))


def test_a_robot_standing_while_the_world_is_starved_is_not_stuck():
    """move_base's timers count ROS time (the sim's under use_sim_time): no progress needs simulated time."""
    real = FakeTime()
    clock = SimClock(50.0, speed_factor=4.0, clock=real)
    watch = ProgressWatch(10.0)
    here = Pose2D(1.0, 2.0, 0.0)
    assert not watch.stalled(here, clock.now())
    run(clock, real, [0.5] * 40)  # 20 s of real time, 80 s at speed factor 4 had the world kept up
    assert not watch.stalled(here, clock.now())  # 40 ticks of 2 periods: 6.4 simulated s
    run(clock, real, [0.02] * 50)  # the world on time again: 4 simulated s more
    assert watch.stalled(here, clock.now())
