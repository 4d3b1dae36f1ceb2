"""Route timetables: parsing entries, which routes are due when, clock jumps, daylight saving, the thread.

Clocks are injected: a wall and a monotonic clock the test moves, and a ``local()`` that is UTC, a
fake Berlin (fixed offsets switching at the 2024 changes) or the real Europe/Berlin via TZ.
"""

import os
import threading
import time
from datetime import datetime, timedelta, timezone

import pytest

from flask_move_server.core.errors import BadRoute
from flask_move_server.missions import schedule
from flask_move_server.missions.route import Route
from flask_move_server.missions.scheduler import Scheduler, due_routes
from tests.conftest import wait_for

MONDAY = (2024, 3, 4)  # a Monday; 2024-03-09 is a Saturday
SPRING = datetime(2024, 3, 31, 1, 0, tzinfo=timezone.utc).timestamp()  # Berlin: 02:00 CET -> 03:00 CEST
AUTUMN = datetime(2024, 10, 27, 1, 0, tzinfo=timezone.utc).timestamp()  # Berlin: 03:00 CEST -> 02:00 CET


def at(year, month, day, hour, minute, second=0.0):
    """Epoch seconds of a UTC time (the local time of ``utc_local``)."""
    return datetime(year, month, day, hour, minute, tzinfo=timezone.utc).timestamp() + second


def utc_local(epoch):
    return datetime.fromtimestamp(epoch, timezone.utc)


def fake_berlin(epoch):
    """Berlin's local time in 2024 from fixed offsets: CEST between the two changes, CET outside."""
    offset = 7200 if SPRING <= epoch < AUTUMN else 3600
    return datetime.fromtimestamp(epoch + offset, timezone.utc).replace(tzinfo=None)


@pytest.fixture
def real_berlin(monkeypatch):
    """``datetime.fromtimestamp`` in the real Europe/Berlin zone (TZ and tzset), restored afterwards."""
    if not hasattr(time, "tzset") or not os.path.exists("/usr/share/zoneinfo/Europe/Berlin"):
        pytest.skip("no tzset or no zone data for Europe/Berlin")
    monkeypatch.setenv("TZ", "Europe/Berlin")
    time.tzset()
    yield datetime.fromtimestamp
    monkeypatch.undo()
    time.tzset()


def route(name, *entries):
    return Route(name, ("kitchen", "dock"), schedule=tuple(entries))


class Clocks:
    """A wall clock and a monotonic clock moved by the test; ``step`` moves both, ``set_wall`` only the wall."""

    def __init__(self, wall):
        self.now, self.mono = wall, 1000.0

    def wall(self):
        return self.now

    def monotonic(self):
        return self.mono

    def step(self, seconds):
        self.now += seconds
        self.mono += seconds

    def set_wall(self, wall):
        self.now = wall


class Robot:
    """The scheduler's surroundings: the active map's routes and the runs it started."""

    def __init__(self, *routes):
        self.routes = list(routes)
        self.started = []

    def on_due(self, route):
        self.started.append(route.name)


def scheduler(robot, clocks, local=utc_local):
    return Scheduler(lambda: robot.routes, robot.on_due, wall=clocks.wall, monotonic=clocks.monotonic, local=local)


def every_minute(sched, clocks, minutes):
    """What the thread does for ``minutes`` minutes: a check just after each minute begins."""
    for _ in range(minutes):
        clocks.step(60.0)
        sched.check()


# -- parse ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("entry, text, days", [
    ("21:30", "21:30", range(7)),
    ("9:05", "09:05", range(7)),
    ("Mon-Fri 09:00", "mon-fri 09:00", range(5)),
    ("sat,sun 10:15", "sat,sun 10:15", (5, 6)),
    ("fri-mon 08:00", "fri-mon 08:00", (4, 5, 6, 0)),
    # said once each, in the week's order (issue 34: "mon,mon,mon 10:00" was kept as it came)
    ("mon,mon,mon 10:00", "mon 10:00", (0,)),
    ("wed,mon-tue 07:00", "mon-wed 07:00", (0, 1, 2)),
    ("sun,mon 07:00", "sun,mon 07:00", (6, 0)),
    ("sun,wed,mon,sat 07:00", "wed,sat-mon 07:00", (2, 5, 6, 0)),
    ("mon-sun 06:00", "06:00", range(7)),
    ("sat-fri 06:00", "06:00", range(7)),
    ("tue,thu 18:45", "tue,thu 18:45", (1, 3)),
])
def test_an_entry_reads_as_its_canonical_text_and_days(entry, text, days):
    slot = schedule.parse(entry)
    assert slot.text == text
    assert slot.days == frozenset(days)


@pytest.mark.parametrize("entry, says", [
    ("25:00", "not a time of day (00:00 to 23:59)"),
    ("12:60", "not a time of day (00:00 to 23:59)"),
    ("noon", "is not a time; write \"21:30\""),
    ("xyz 10:00", "names a day it does not know; days are mon, tue"),
    ("", "is not a time; write"),
    (5, "each entry is a time as text"),
    ("9" * 1000, "each entry is a time as text"),
    ("\u0661\u0660:\u0663\u0660", "is not a time"),  # Arabic-Indic digits were taken as 10:30
    ("\uff11\uff10:\uff13\uff10", "is not a time"),  # full-width digits too
    ("mon\u200510:30", "is not a time"),  # a Unicode space between the days and the time
])
def test_a_wrong_entry_says_what_a_time_looks_like(entry, says):
    with pytest.raises(BadRoute) as caught:
        schedule.parse(entry)
    assert says in str(caught.value)
    assert len(str(caught.value)) < 400  # a 1000-character entry is quoted cut short


# -- next_due ------------------------------------------------------------------------------------------

def test_next_due_is_the_next_start_of_any_entry():
    slots = [schedule.parse("21:30"), schedule.parse("mon-fri 09:00")]
    assert schedule.next_due(slots, datetime(*MONDAY, 21, 29, 59)) == datetime(*MONDAY, 21, 30)
    assert schedule.next_due(slots, datetime(*MONDAY, 21, 30)) == datetime(2024, 3, 5, 9, 0)
    friday_night = datetime(2024, 3, 8, 21, 45)
    assert schedule.next_due(slots[1:], friday_night) == datetime(2024, 3, 11, 9, 0)
    assert schedule.next_due(slots[:1], friday_night) == datetime(2024, 3, 9, 21, 30)


def test_next_due_keeps_the_time_zone_and_is_none_without_entries():
    after = datetime(*MONDAY, 22, 0, tzinfo=timezone(timedelta(hours=1)))
    assert schedule.next_due([schedule.parse("sun 07:05")], after) == datetime(2024, 3, 10, 7, 5,
                                                                                 tzinfo=after.tzinfo)
    assert schedule.next_due([], after) is None


# -- which routes are due --------------------------------------------------------------------------------

def test_a_route_is_due_once_in_the_check_just_after_its_minute():
    rounds, fired = route("rounds", "21:30"), {}
    assert due_routes([rounds], at(*MONDAY, 21, 29, 59), at(*MONDAY, 21, 30, 0.2), utc_local, fired) == [rounds]
    assert due_routes([rounds], at(*MONDAY, 21, 30, 0.2), at(*MONDAY, 21, 31, 0.2), utc_local, fired) == []


def test_a_check_that_starts_after_the_minute_does_not_run_it():
    rounds = route("rounds", "21:30")
    assert due_routes([rounds], at(*MONDAY, 21, 30, 0.0), at(*MONDAY, 21, 31, 0.2), utc_local, {}) == []


@pytest.mark.parametrize("entry, monday, saturday", [
    ("mon-fri 09:00", True, False),
    ("sat,sun 09:00", False, True),
    ("fri-mon 09:00", True, True),
    ("09:00", True, True),
])
def test_days_decide_whether_a_route_runs(entry, monday, saturday):
    rounds = route("rounds", entry)
    for day, expected in (((2024, 3, 4), monday), ((2024, 3, 9), saturday)):
        due = due_routes([rounds], at(*day, 8, 59, 59), at(*day, 9, 0, 0.2), utc_local, {})
        assert due == ([rounds] if expected else []), day


def test_two_entries_in_the_same_minute_start_one_run():
    robot = Robot(route("rounds", "21:30", "mon 21:30"), route("patrol", "mon-fri 21:30"), route("idle"))
    clocks = Clocks(at(*MONDAY, 21, 29, 59))
    sched = scheduler(robot, clocks)
    clocks.step(1.2)
    sched.check()
    assert robot.started == ["rounds", "patrol"]


def test_a_route_due_twice_in_one_check_starts_once():
    rounds = route("rounds", "21:30", "21:31")
    due = due_routes([rounds], at(*MONDAY, 21, 29, 59), at(*MONDAY, 21, 31, 0.2), utc_local, {})
    assert due == [rounds]


def test_the_routes_are_asked_afresh_at_every_check():
    robot = Robot(route("rounds", "21:30"))
    clocks = Clocks(at(*MONDAY, 21, 29, 0.2))
    sched = scheduler(robot, clocks)
    every_minute(sched, clocks, 1)
    robot.routes = [route("patrol", "21:31")]  # another map made active
    every_minute(sched, clocks, 1)
    assert robot.started == ["rounds", "patrol"]


def test_a_failing_route_list_or_start_is_logged_and_the_others_still_run(caplog):
    robot = Robot(route("rounds", "21:30"), route("patrol", "21:30"))
    clocks = Clocks(at(*MONDAY, 21, 28, 0.2))
    asked = []

    def routes():
        asked.append(1)
        if len(asked) == 1:
            raise OSError("the waypoints file is being written")
        return robot.routes

    def on_due(r):
        if r.name == "rounds":
            raise RuntimeError("the robot is e-stopped")
        robot.on_due(r)

    sched = Scheduler(routes, on_due, wall=clocks.wall, monotonic=clocks.monotonic, local=utc_local)
    every_minute(sched, clocks, 2)
    assert robot.started == ["patrol"]
    assert "could not read the routes" in caplog.text
    assert "could not start the scheduled run of route 'rounds'" in caplog.text


# -- clock changes ---------------------------------------------------------------------------------------

def test_a_server_started_after_the_minute_does_not_run_it_late():
    robot = Robot(route("rounds", "21:30"))
    clocks = Clocks(at(*MONDAY, 21, 30, 30.0))
    sched = scheduler(robot, clocks)
    clocks.step(30.2)
    sched.check()
    every_minute(sched, clocks, 5)
    assert robot.started == []


def test_a_clock_jumping_hours_ahead_runs_nothing_in_between(caplog):
    robot = Robot(route("morning", "16:00"), route("evening", "18:00"), route("late", "20:59"),
                  route("now", "21:01"), route("next", "21:02"))
    clocks = Clocks(at(*MONDAY, 15, 0, 0.2))  # the Pi booted at its last shutdown time
    sched = scheduler(robot, clocks)
    caplog.set_level("INFO", logger="flask_move_server")
    clocks.step(60.0)
    clocks.set_wall(at(*MONDAY, 21, 1, 0.2))  # NTP: six hours later
    sched.check()
    every_minute(sched, clocks, 1)
    assert robot.started == ["now", "next"]
    assert "the clock jumped by +6h00m; schedules in between are not run" in caplog.text


def test_a_clock_set_back_an_hour_runs_no_route_twice(caplog):
    robot = Robot(route("tea", "21:10"), route("rounds", "21:30"), route("lights", "21:50"))
    clocks = Clocks(at(*MONDAY, 21, 5, 0.2))
    sched = scheduler(robot, clocks)
    caplog.set_level("INFO", logger="flask_move_server")
    every_minute(sched, clocks, 40)  # to 21:45
    clocks.set_wall(clocks.now - 3600)  # to 20:45
    every_minute(sched, clocks, 70)  # to 21:55
    assert robot.started == ["tea", "rounds", "lights"]
    assert "the clock jumped by -1h00m" in caplog.text


def test_a_clock_set_back_a_month_runs_the_next_day_as_usual():
    robot = Robot(route("rounds", "09:00"))
    clocks = Clocks(at(2024, 4, 4, 8, 58, 0.2))  # an RTC that ran a month ahead
    sched = scheduler(robot, clocks)
    every_minute(sched, clocks, 1)
    clocks.set_wall(at(*MONDAY, 8, 58, 0.2))
    every_minute(sched, clocks, 3)
    assert robot.started == ["rounds"]


# -- daylight saving ---------------------------------------------------------------------------------------

@pytest.fixture(params=["fake", "real"])
def berlin(request):
    return fake_berlin if request.param == "fake" else request.getfixturevalue("real_berlin")


def test_an_hour_skipped_in_spring_runs_nothing_in_it(berlin):
    robot = Robot(route("early", "01:59"), route("skipped", "02:30"), route("after", "03:00"))
    clocks = Clocks(SPRING - 2 * 3600 + 0.2)  # 00:00 CET on Sunday
    sched = scheduler(robot, clocks, berlin)
    every_minute(sched, clocks, 26 * 60)  # a 23-hour Sunday, then to 03:00 on Monday, when 02:30 exists again
    assert robot.started == ["early", "after", "early", "skipped", "after"]


def test_an_hour_repeated_in_autumn_runs_its_routes_once(berlin):
    robot = Robot(route("rounds", "02:30"), route("early", "02:00"), route("later", "03:00"))
    clocks = Clocks(AUTUMN - 2 * 3600 + 0.2)  # 01:00 CEST
    sched = scheduler(robot, clocks, berlin)
    every_minute(sched, clocks, 4 * 60)  # 02:00-02:59 twice, then to 04:00 CET
    assert robot.started == ["early", "rounds", "later"]


# -- the thread ----------------------------------------------------------------------------------------------

def scheduler_running():
    return any(t.name == "route-scheduler" for t in threading.enumerate())


def running_wall(start):
    """A wall clock that runs in real time from ``start``."""
    t0 = time.monotonic()
    return lambda: start + time.monotonic() - t0


def test_the_thread_starts_a_route_just_after_its_minute():
    started, done = [], threading.Event()

    def on_due(r):
        started.append((r.name, threading.current_thread().name))
        done.set()

    wall = running_wall(at(*MONDAY, 21, 29, 59.6))
    with Scheduler(lambda: [route("rounds", "21:30")], on_due, wall=wall, local=utc_local):
        assert done.wait(3), "the 21:30 route was not started"
        when = wall()
    assert started == [("rounds", "route-scheduler")]
    assert at(*MONDAY, 21, 30, 0.0) < when < at(*MONDAY, 21, 30, 1.0)
    assert not scheduler_running()


def test_close_returns_at_once_while_the_thread_sleeps_till_the_next_minute():
    sched = Scheduler(lambda: [], lambda r: None, wall=lambda: at(*MONDAY, 21, 30, 1.0), local=utc_local)
    sched.start()
    time.sleep(0.05)
    t0 = time.monotonic()
    sched.close()
    assert time.monotonic() - t0 < 1.0
    assert not scheduler_running()
    sched.close()  # twice is fine


def test_a_failing_check_does_not_end_the_thread(caplog):
    def routes():
        raise RuntimeError("no map loaded")

    sched = Scheduler(routes, lambda r: None, wall=running_wall(at(*MONDAY, 21, 29, 59.7)), local=utc_local)
    with sched:
        wait_for(lambda: "could not read the routes" in caplog.text, timeout=3, message="the check's log")
        assert scheduler_running()


def test_a_clock_leaping_at_every_look_does_not_make_the_thread_spin():
    looks = []

    def leaping_wall():
        looks.append(1)
        return at(*MONDAY, 21, 0, 59.95) + 3600 * len(looks)  # always 50 ms before a minute, hours later

    with Scheduler(lambda: [], lambda r: None, wall=leaping_wall, local=utc_local):
        time.sleep(1.0)
    assert len(looks) <= 12  # a look to sleep and one to check, at most every 0.25 s
