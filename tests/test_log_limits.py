"""Storms of log lines are throttled: a goal storm logged 180-300 lines a second (an SD card's
worth of writes), one per goal, and actionlib's "already in the DONE state" errors with them."""

import logging

from flask_move_server.process.log_limits import Throttled, ThrottleFilter


class Clock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


def test_a_storm_logs_its_first_lines_then_says_how_many_were_left_out(caplog):
    clock = Clock()
    lines = Throttled(logging.getLogger("storm"), "goal lines", burst=10, interval=10.0, clock=clock)
    with caplog.at_level(logging.INFO, logger="storm"):
        for n in range(300):  # a second of a goal storm
            lines.info("goal %d: pose", n)
        clock.now += 10.0
        lines.info("goal %d: pose", 300)
    messages = [r.getMessage() for r in caplog.records]
    assert messages[:10] == ["goal {}: pose".format(n) for n in range(10)]
    assert messages[10] == "290 more goal lines left out of the log in 10 s"
    assert messages[11:] == ["goal 300: pose"]


def test_a_quiet_robot_logs_every_goal(caplog):
    clock = Clock()
    lines = Throttled(logging.getLogger("quiet"), "goal lines", burst=10, interval=10.0, clock=clock)
    with caplog.at_level(logging.INFO, logger="quiet"):
        for n in range(30):  # one goal every 2 s
            lines.info("goal %d: pose", n)
            clock.now += 2.0
    assert len(caplog.records) == 30


def test_another_librarys_storm_lines_are_filtered_and_counted(caplog):
    clock = Clock()
    logger = logging.getLogger("rosout-test")
    storm = ThrottleFilter(["already in the DONE state"], burst=2, interval=60.0, clock=clock)
    logger.addFilter(storm)
    try:
        with caplog.at_level(logging.INFO, logger="rosout-test"):
            for _ in range(50):
                logger.error("Got a result when we were already in the DONE state")
            logger.error("something else entirely")
            clock.now += 60.0
            logger.error("Got a result when we were already in the DONE state")
    finally:
        logger.removeFilter(storm)
    messages = [r.getMessage() for r in caplog.records]
    assert messages[:2] == ["Got a result when we were already in the DONE state"] * 2
    assert messages[2] == "something else entirely"
    assert messages[3] == ("Got a result when we were already in the DONE state "
                           "(48 more like it left out of the log in 60 s)")
    assert len(messages) == 4


def test_a_goal_storm_against_the_real_navigator_logs_a_bounded_number_of_lines(ready_robot, caplog):
    from flask_move_server.core.geometry import Goal, Pose2D
    from flask_move_server.ros.navigator import GOAL_LINES_BURST

    with caplog.at_level(logging.INFO, logger="flask_move_server.ros.navigator"):
        for n in range(100):
            ready_robot.goto(Goal(Pose2D(float(n % 7), 0.0, 0.0)))
    goal_lines = [r for r in caplog.records if r.getMessage().startswith("goal ")]
    assert len(goal_lines) <= GOAL_LINES_BURST
