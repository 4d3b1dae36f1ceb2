"""A stuck robot on real ROS topics: the server's watch, navigator and teleop against a base whose wheels
turn without moving it (tests/stuck_world.py: odometry counting the commands, the laser cast from where
the robot really is) and a real actionlib move_base (tests/standins/move_base.py).

Wedged while a goal drives it, the robot says so (``/status``, a ``stuck`` event), stops commanding,
backs out slowly when the laser shows room, and sends the same goal again; with a wall behind it
waits for its owner, and the goal ends ``stuck``. Goals aborted at once while it touches something
count as stuck too; goals aborted at once in the open do not. Pushed by the joystick, it only says so.
"""

import time

import pytest

from flask_move_server import config
from flask_move_server.core.errors import NotStuck, Pressed
from flask_move_server.core.geometry import Goal, Pose2D
from flask_move_server.recovery import footprint
from flask_move_server.recovery.recovery import Recovery
from flask_move_server.recovery.watch import StuckWatch
from tests.conftest import ROOT, wait_for
from tests.standins.move_base import ABORT_X, HOLD_X
from tests.stuck_world import WedgedBase

FOOTPRINT = footprint.read(ROOT + "/config")
OPEN_FLOOR = Pose2D(2.5, 1.0, 0.0)  # the living room, facing the kitchen door: metres free behind
BACK_TO_THE_WALL = Pose2D(-1.83, 3.5, 0.0)  # the office, its back 3 cm from the west wall
NOSE_ON_THE_WALL = Pose2D(-1.86, 3.5, 3.14159)  # the office, facing the west wall, touching it


class Relocalize:
    def __init__(self):
        self.calls = 0

    def __call__(self):
        self.calls += 1


@pytest.fixture
def stuck(ready_robot, robot_config, bus, unique_name, request):
    """The robot with its recovery and watch, and a WedgedBase at the test's ``truth``."""
    truth = getattr(request, "param", OPEN_FLOOR)
    world = WedgedBase(unique_name, truth, robot_config.ros.frames.base_link, robot_config.ros.frames.map)
    relocalize = Relocalize()
    recovery = Recovery(ready_robot, config.StuckConfig(), FOOTPRINT, relocalize=relocalize, events=bus)
    ready_robot.recovery = recovery
    watch = StuckWatch(recovery, ready_robot.node, ready_robot, unique_name + "/scan", unique_name + "/odom",
                       robot_config.ros.frames.base_link, period=0.2).start()
    told = []
    bus.listen("stuck", lambda data: told.append(data["state"]))
    yield ready_robot, world, recovery, relocalize, told
    watch.close()
    recovery.close()
    world.close()


def stuck_state(robot):
    return robot.status()["stuck"]["state"]


def push_until_pressed(robot, seconds=4.0):
    """Drive forward by joystick, as an owner would, until the robot says it is pressed against something."""
    deadline = time.monotonic() + seconds
    while stuck_state(robot) != "stuck" and time.monotonic() < deadline:
        robot.teleop(0.2, 0.0)
        time.sleep(0.1)


def test_wedged_by_its_goal_it_says_so_backs_out_and_goes_on(stuck, move_base):
    robot, world, recovery, relocalize, told = stuck
    seq = robot.goto(Goal(Pose2D(HOLD_X, 0.0, 0.0), "kitchen"))
    world.pushing = 0.2  # move_base drives it on; the wheels turn, the robot does not move
    wait_for(lambda: robot.status()["navigation"]["state"] == "stuck", timeout=10, message="the goal held, stuck")
    world.pushing = 0.0  # move_base let go of the goal
    nav = robot.status()["navigation"]
    assert nav["target"] == "kitchen" and nav["message"].startswith("Stuck")
    assert robot.navigator.wait(seq, 0) == ("active", None)  # a waiting client goes on waiting
    wait_for(lambda: len(move_base.goals) == 2, timeout=15, message="the same goal sent again")
    assert robot.status()["navigation"]["state"] == "active" and robot.status()["navigation"]["goal_id"] == seq
    assert told == ["stuck", "backing_out", "free"]  # each as a ``stuck`` event
    backed = world.backed_out()
    assert backed and all(linear == pytest.approx(-0.1) for linear, _ in backed)  # slowly, straight
    assert OPEN_FLOOR.x - world.truth.x == pytest.approx(0.3, abs=0.08)  # it came 0.3 m back
    assert relocalize.calls == 1
    assert recovery.status()["count"] == 1 and recovery.status()["freed"] == 1
    assert move_base.goals[1][1].target_pose.pose.position.x == HOLD_X


def test_wedged_at_an_angle_with_its_back_blocked_too_it_pulls_out_forwards_and_goes_on(stuck, move_base):
    robot, world, recovery, _, told = stuck
    world.blocked = lambda linear: linear < 0 or world.pushing > 0  # a table's corner beside its back
    seq = robot.goto(Goal(Pose2D(HOLD_X, 0.0, 0.0), "kitchen"))
    world.pushing = 0.2
    wait_for(lambda: robot.status()["navigation"]["state"] == "stuck", timeout=10, message="the goal held, stuck")
    world.pushing = 0.0
    wait_for(lambda: len(move_base.goals) == 2, timeout=20, message="the same goal sent again")
    assert world.backed_out(), "it tried backing out first"
    assert world.truth.x - OPEN_FLOOR.x == pytest.approx(0.3, abs=0.08)  # then came 0.3 m forwards
    assert recovery.status()["freed"] == 1 and robot.status()["navigation"]["goal_id"] == seq
    assert told[-1] == "free"


@pytest.mark.parametrize("stuck", [BACK_TO_THE_WALL], indirect=True)
def test_with_a_wall_behind_it_does_not_back_out_and_the_goal_ends_stuck(stuck, move_base):
    robot, world, recovery, _, told = stuck
    seq = robot.goto(Goal(Pose2D(HOLD_X, 0.0, 0.0), None))
    world.pushing = 0.2
    state, why = robot.navigator.wait(seq, 15)
    world.pushing = 0.0
    assert state == "stuck" and "drive it out with the joystick" in why and "not clear" in why
    assert world.backed_out() == []
    assert stuck_state(robot) == "stuck" and robot.status()["navigation"]["state"] == "stuck"
    assert len(move_base.goals) == 1  # not sent again
    robot.stop()  # the owner takes over
    assert stuck_state(robot) == "free"


@pytest.mark.parametrize("stuck", [NOSE_ON_THE_WALL], indirect=True)
def test_goals_aborted_at_once_while_it_touches_a_wall_are_stuck_and_it_backs_off(stuck, move_base):
    robot, world, recovery, relocalize, told = stuck
    first = robot.goto(Goal(Pose2D(ABORT_X, 0.0, 0.0), None))
    assert robot.navigator.wait(first, 5)[0] == "aborted"  # once: could be a goal nobody reaches
    second = robot.goto(Goal(Pose2D(ABORT_X, 1.0, 0.0), None))
    wait_for(lambda: len(move_base.goals) == 3, timeout=15, message="the second goal sent again after backing off")
    assert robot.navigator.wait(second, 5)[0] == "aborted"  # this stand-in aborts it again: move_base's word stands
    assert world.backed_out() and relocalize.calls == 1
    assert world.truth.x - NOSE_ON_THE_WALL.x > 0.2  # backed off the wall it faced
    assert recovery.status()["freed"] == 1


def test_goals_aborted_at_once_in_the_open_are_just_aborted(stuck, move_base):
    robot, world, recovery, _, _ = stuck
    for y in (0.0, 1.0, 2.0):
        seq = robot.goto(Goal(Pose2D(ABORT_X, y, 0.0), None))
        assert robot.navigator.wait(seq, 5)[0] == "aborted"
    assert len(move_base.goals) == 3 and world.backed_out() == [] and recovery.status()["count"] == 0


def test_pushed_by_the_joystick_it_says_so_stops_and_is_free_once_it_moves(stuck):
    robot, world, recovery, _, told = stuck
    push_until_pressed(robot)
    status = robot.status()
    assert status["stuck"]["state"] == "stuck" and status["stuck"]["message"].startswith("Pressed against something")
    assert not status["teleop"]["active"]  # it stopped commanding the motors against the wall
    assert world.backed_out() == [] and status["stuck"]["waiting"]  # the owner drives: no back-out by itself
    with pytest.raises(Pressed) as refused:  # pushing on only slides its position into the wall
        robot.teleop(0.2, 0.3)
    assert "pressed against something ahead" in str(refused.value)
    robot.teleop(0.0, 0.5)  # turning is not refused, nor driving back
    world.blocked = lambda linear: False
    for _ in range(30):
        robot.teleop(-0.2, 0.0)
        if stuck_state(robot) == "free":
            break
        time.sleep(0.1)
    assert stuck_state(robot) == "free"  # the laser saw it move: free again


def test_a_push_on_its_way_as_the_robot_is_found_pressed_is_stopped_and_refused(stuck):
    robot, world, recovery, _, told = stuck
    world.blocked = lambda linear: False
    wait_for(lambda: robot.teleop(0.2, 0.0) and recovery.sensing.came() == 1, timeout=5,
             message="the watch seeing it drive forward")
    command = robot.teleop_control.command

    def found_pressed_meanwhile(linear, angular, **options):
        recovery.blocked()  # the watch says so after this push passed the check, before it reached the motors
        return command(linear, angular, **options)

    robot.teleop_control.command = found_pressed_meanwhile
    try:
        with pytest.raises(Pressed):
            robot.teleop(0.2, 0.0)
    finally:
        robot.teleop_control.command = command
    assert stuck_state(robot) == "stuck" and not robot.status()["teleop"]["active"]  # it does not drive on


def test_asked_to_back_out_it_backs_out_slowly_and_waits_and_a_free_robot_says_it_is_not_stuck(stuck):
    robot, world, recovery, relocalize, told = stuck
    with pytest.raises(NotStuck):
        robot.back_out()
    push_until_pressed(robot)
    assert robot.back_out()["state"] in ("stuck", "backing_out")
    wait_for(lambda: stuck_state(robot) == "free", timeout=15, message="backed out")
    assert told == ["stuck", "backing_out", "free"]
    assert OPEN_FLOOR.x - world.truth.x == pytest.approx(0.3, abs=0.08) and relocalize.calls == 1
    assert recovery.status()["freed"] == 1 and not robot.status()["teleop"]["active"]


def test_the_joystick_ends_a_back_out_the_owner_asked_for(stuck):
    robot, world, recovery, _, _ = stuck
    push_until_pressed(robot)
    robot.back_out()
    wait_for(lambda: stuck_state(robot) == "backing_out", timeout=5, message="backing out")
    robot.teleop(0.0, 0.5)  # the owner turns it instead
    assert stuck_state(robot) == "free" and robot.status()["teleop"]["by"] == "owner"
    time.sleep(0.2)  # a command of the back-out's on its way now lands
    backed = len(world.backed_out())
    time.sleep(0.5)
    assert len(world.backed_out()) == backed  # no more of them


@pytest.mark.parametrize("stuck", [BACK_TO_THE_WALL], indirect=True)
def test_a_run_stuck_on_its_way_waits_as_stuck_misses_nothing_and_resume_goes_there_again(stuck, move_base, store):
    from flask_move_server.missions.executor import RunExecutor
    from flask_move_server.missions.history import RunHistory
    from flask_move_server.missions.route import make_route
    from flask_move_server.waypoints import make_waypoint

    robot, world, _, _, _ = stuck
    store.put(make_waypoint("hall", HOLD_X, 0.0, 0.0))
    runs = RunExecutor(robot, store, RunHistory(str(store.path) + ".runs.json"))
    robot.runs = runs
    try:
        run = runs.start(make_route(None, {"waypoints": ["hall", "dock"]}, scheduled=False))
        world.pushing = 0.2
        wait_for(lambda: runs.get(run["id"])["state"] == "stuck", timeout=15, message="the run stuck")
        world.pushing = 0.0
        now = runs.get(run["id"])
        assert now["missed"] == [] and now["current"]["name"] == "hall"
        assert now["message"].startswith("Stuck on the way to hall: Stuck") and "resume the run" in now["message"]
        world.blocked = lambda linear: False  # the owner freed it
        assert runs.resume(run["id"])["state"] == "running"
        wait_for(lambda: len(move_base.goals) == 2, timeout=10, message="hall sent again")
        assert move_base.goals[1][1].target_pose.pose.position.x == HOLD_X
    finally:
        runs.close()
