"""The reporter tells the event bus what changed in the robot, and only that; the plan is thinned."""

from flask_move_server.core.events import EventBus
from flask_move_server.core.reporter import POSE_REFRESH, Reporter
from flask_move_server.ros.plan import MAX_POINTS, plan_event, thin
from tests.fake_robot import FakeRobot


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


class MovingRobot(FakeRobot):
    """The fake robot with a pose and motors a test sets."""

    def __init__(self):
        super().__init__()
        self.where = {"x": 0.0, "y": 0.0, "yaw": 0.0, "frame": "map", "age": 0.01, "source": "tf"}
        self.left = 0.0
        self.remaining = None

    def status(self):
        status = super().status()
        status["pose"] = dict(self.where) if self.where else None
        status["motors"] = dict(status["motors"], left=self.left, command_age=self.remaining)
        status["teleop"] = dict(status["teleop"], remaining=self.remaining)
        return status


def _reporter(robot):
    bus, clock = EventBus(), Clock()
    sub = bus.subscribe()
    return Reporter(robot, bus, clock=clock), sub, clock


def _kinds(sub):
    kinds = []
    event = sub.next(0)
    while event is not None:
        kinds.append(event[0])
        event = sub.next(0)
    return kinds


def test_the_first_sample_tells_pose_status_and_estop():
    reporter, sub, _ = _reporter(MovingRobot())
    reporter.sample()
    assert sorted(_kinds(sub)) == ["estop", "pose", "status"]


def test_nothing_is_told_again_while_nothing_changes_but_the_ticking_fields():
    robot = MovingRobot()
    reporter, sub, clock = _reporter(robot)
    reporter.sample()
    _kinds(sub)
    for tick in range(5):
        robot.where["age"] += 0.1  # ages, teleop remaining and command ages tick by themselves
        robot.remaining = 0.5 - tick * 0.1
        clock.now += 0.1
        reporter.sample()
    assert _kinds(sub) == []


def test_a_move_is_told_as_a_pose_and_a_motor_change_as_a_status():
    robot = MovingRobot()
    reporter, sub, clock = _reporter(robot)
    reporter.sample()
    _kinds(sub)
    robot.where["x"] = 0.05
    robot.left = 0.4
    clock.now += 0.1
    reporter.sample()
    assert sorted(_kinds(sub)) == ["pose", "status"]
    assert reporter._events.latest("pose")["x"] == 0.05
    assert reporter._events.latest("status")["motors"]["left"] == 0.4


def test_a_pose_at_rest_is_told_again_once_a_second_with_its_age():
    robot = MovingRobot()
    reporter, sub, clock = _reporter(robot)
    reporter.sample()
    _kinds(sub)
    clock.now += POSE_REFRESH
    robot.where["age"] = 1.2
    reporter.sample()
    assert sub.next(0) == ("pose", robot.where)


def test_a_pose_becoming_unknown_is_told():
    robot = MovingRobot()
    reporter, sub, clock = _reporter(robot)
    reporter.sample()
    _kinds(sub)
    robot.where = None
    clock.now += 0.1
    reporter.sample()
    assert sub.next(0) == ("pose", None)


def test_an_estop_engage_is_told_at_once_without_waiting_for_a_sample():
    robot = MovingRobot()
    reporter, sub, _ = _reporter(robot)
    reporter.sample()
    _kinds(sub)
    robot.engage_estop("api")
    kind, data = sub.next(0)
    assert kind == "estop" and data["latched"] is True and data["source"] == "api"
    reporter.sample()  # the next sample finds nothing new
    assert _kinds(sub) == []
    robot.release_estop()
    reporter.sample()
    assert sub.next(0) == ("estop", {"latched": False, "source": None, "since": None})


def test_the_thread_samples_and_closes():
    robot = MovingRobot()
    bus = EventBus()
    sub = bus.subscribe()
    reporter = Reporter(robot, bus).start()
    try:
        assert sub.next(5) is not None
    finally:
        reporter.close()
        reporter.close()


def test_a_long_plan_is_thinned_to_the_limit_keeping_both_ends():
    points = [(i * 0.01, 0.5) for i in range(4001)]
    kept = thin(points, MAX_POINTS)
    assert len(kept) <= MAX_POINTS and kept[0] == points[0] and kept[-1] == points[-1]
    event = plan_event("map", [(1.23456, 2.0)])
    assert event == {"frame": "map", "poses": [[1.235, 2.0]]}


class FailingRobot(MovingRobot):
    def __init__(self):
        super().__init__()
        self.failures = 3

    def status(self):
        if self.failures:
            self.failures -= 1
            raise RuntimeError("a part's bug")
        return super().status()


def test_a_failing_sample_is_logged_once_and_sampling_goes_on(caplog):
    robot = FailingRobot()
    bus = EventBus()
    sub = bus.subscribe()
    reporter = Reporter(robot, bus, rate=50).start()
    try:
        assert sub.next(5) is not None  # told once the robot answers again
    finally:
        reporter.close()
    failures = [r for r in caplog.records if "sampling the robot for events failed" in r.getMessage()]
    assert len(failures) == 1


class EngagedMidSample(MovingRobot):
    """The e-stop is pressed while the reporter is reading the rest of the robot."""

    press = False

    def status(self):
        status = super().status()  # read before the press: not latched
        if self.press:
            self.engage_estop("button")
        return status


def test_an_estop_pressed_during_a_sample_is_never_told_as_released_afterwards():
    robot = EngagedMidSample()
    reporter, sub, clock = _reporter(robot)
    reporter.sample()
    robot.press = True
    clock.now += 0.1
    reporter.sample()
    assert reporter._events.latest("estop")["latched"] is True


class CountingRobot(MovingRobot):
    samples = 0

    def status(self):
        self.samples += 1
        return super().status()


def _settle(seconds=0.3):
    import time

    time.sleep(seconds)  # at rate 50, fifteen samples' time


def test_nobody_reading_means_no_sampling_and_a_new_reader_is_primed_with_the_robot_now():
    robot = CountingRobot()
    bus = EventBus()
    reporter = Reporter(robot, bus, rate=50).start()
    try:
        _settle()
        assert robot.samples == 0, "the robot was sampled with nobody reading the events"

        robot.where["x"] = 2.5  # the robot moved while no page was open
        sub = bus.subscribe()
        assert robot.samples == 1, "a new reader's stream was primed without reading the robot"
        primed = dict(_events(sub))
        assert primed["pose"]["x"] == 2.5

        robot.where["x"] = 3.0
        assert _next_pose(sub)["x"] == 3.0, "the move was not told while someone reads"

        sub.close()
        _settle()
        after_close = robot.samples
        _settle()
        assert robot.samples == after_close, "sampling went on after the last reader left"
    finally:
        reporter.close()


def _events(sub):
    events = []
    event = sub.next(0)
    while event is not None:
        events.append(event)
        event = sub.next(0)
    return events


def _next_pose(sub, timeout=5):
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        event = sub.next(0.1)
        if event is not None and event[0] == "pose":
            return event[1]
    return None
