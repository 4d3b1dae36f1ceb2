"""runs.json: what RunHistory writes is the kept runs as JSON, newest first, whatever it reuses to make it."""

import json
import time

import pytest

from flask_move_server.missions.executor import RunExecutor
from flask_move_server.missions.history import RunHistory
from flask_move_server.missions.route import Route, make_route
from flask_move_server.missions.run import FAILED, SUCCEEDED, Run
from tests.conftest import wait_for
from tests.fake_robot import FakeRobot


def written(history):
    history.close()  # the writer's thread writes what is pending
    with open(history.path) as f:
        return f.read()


def test_the_file_is_the_runs_as_json_as_they_are_now(tmp_path):
    path = str(tmp_path / "runs.json")
    history = RunHistory(path)
    route = Route("rounds", ("kitchen", "dock"), loops=2)
    done = Run.of_route(history.next_id, route, "api")
    history.add(done)
    done.visit()
    done.end(SUCCEEDED, "Visited every waypoint (1 loop).")
    history.changed()  # its text is made now, and reused below
    under_way = Run.of_route(history.next_id, route, "schedule")
    history.add(under_way)
    for _ in range(3):
        under_way.visit()
        under_way.advance()
        history.changed()
    text = written(history)
    assert text == json.dumps([under_way.as_dict(), done.as_dict()], ensure_ascii=False) + "\n"
    assert [r["id"] for r in json.loads(text)] == [2, 1]


def test_runs_beyond_the_kept_ones_leave_the_file(tmp_path):
    path = str(tmp_path / "runs.json")
    history = RunHistory(path, keep=2)
    runs = []
    for _ in range(3):
        run = Run.of_route(history.next_id, Route(None, ("dock",)), "api")
        history.add(run)
        run.end(FAILED, "Could not reach dock: no plan.")
        history.changed()
        runs.append(run)
    assert json.loads(written(history)) == [runs[2].as_dict(), runs[1].as_dict()]


def test_progress_is_written_at_most_once_per_interval_and_state_changes_at_once(tmp_path, monkeypatch):
    """A patrol reaching a waypoint every few seconds for months must not rewrite runs.json twice a stop
    (an SD card's wear); a start, a pause or an end is on disk at once."""
    from flask_move_server.waypoints import locked_file

    writes = []
    real = locked_file.atomic_write
    monkeypatch.setattr(locked_file, "atomic_write", lambda path, text, **kw: (writes.append(text),
                                                                                real(path, text, **kw)))
    history = RunHistory(str(tmp_path / "runs.json"))
    history._writer.min_interval = 0.5
    try:
        run = Run.of_route(1, make_route(None, {"waypoints": ["a", "b"], "loops": 0}, scheduled=False), "api")
        history.add(run)
        wait_for(lambda: len(writes) == 1, message="the start written at once")
        for _ in range(20):  # twenty waypoints reached in quick succession
            run.visit()
            run.advance()
            history.changed(progress=True)
        time.sleep(0.2)
        assert len(writes) == 1  # none of them yet: within the interval
        wait_for(lambda: len(writes) == 2, timeout=2, message="the newest progress once the interval passed")
        assert json.loads(writes[-1])[0]["loop"] == 11
        run.end("canceled", "Stopped (POST /stop).")
        history.changed()
        wait_for(lambda: len(writes) == 3, timeout=0.3, message="the end written at once")
    finally:
        history.close()


# a file that cannot be taken (issue 34, item 5) ------------------------------------------------------


def kept(run_id, **changes):
    run = Run.of_route(run_id, Route("rounds", ("kitchen", "dock"), dwell=5.0), "api")
    run.end(SUCCEEDED, "Visited every waypoint (1 loop).")
    return dict(run.as_dict(), **changes)


def set_aside(tmp_path):
    return sorted(p for p in tmp_path.iterdir() if p.name.startswith("runs.json.broken-"))


def test_a_file_that_cannot_be_read_is_set_aside_whole_and_said_once(tmp_path, caplog):
    path = tmp_path / "runs.json"
    text = json.dumps([kept(i) for i in range(49, 0, -1)])[:-1] + ",]"  # one trailing comma: not JSON
    path.write_text(text)
    history = RunHistory(str(path))
    try:
        assert history.all() == [] and history.next_id == 1
        aside = set_aside(tmp_path)
        assert len(aside) == 1 and aside[0].read_text() == text  # the 49 runs are not lost: the owner has them
        warnings = [r.getMessage() for r in caplog.records if "runs.json" in r.getMessage()]
        assert len(warnings) == 1 and "set aside as {}".format(aside[0]) in warnings[0]
        history.add(Run.of_route(history.next_id, Route(None, ("dock",)), "api"))
    finally:
        history.close()
    assert [r["id"] for r in json.loads(path.read_text())] == [1] and set_aside(tmp_path) == aside


BAD_RUNS = [
    {"dwell": 1e308},  # killed the run's worker (OverflowError): every new run got 409 until /stop
    {"dwell": -1},
    {"loops": -3},
    {"loops": True},
    {"index": 7},
    {"state": "flying"},
    {"trigger": "a stranger"},
    {"waypoints": []},
    {"waypoints": ["../../etc"]},
    {"route": "a/b"},
    {"id": "1"},
    {"started": "x" * 10000},
    {"message": ["not", "text"]},
    {"visited": [{"name": "x" * 100000}]},
    {"on_failure": "explode"},
]


@pytest.mark.parametrize("change", BAD_RUNS, ids=[next(iter(c)) + "=" + repr(next(iter(c.values())))[:12]
                                                  for c in BAD_RUNS])
def test_a_kept_run_is_checked_as_the_api_checks_it_and_the_others_stay(tmp_path, change):
    path = tmp_path / "runs.json"
    good = [kept(3), kept(1)]
    text = json.dumps([good[0], kept(2, **change), good[1]])
    path.write_text(text)
    history = RunHistory(str(path))
    try:
        assert [r.id for r in history.all()] == [3, 1]
        assert [r.as_dict() for r in history.all()] == good
    finally:
        history.close()
    aside = set_aside(tmp_path)
    assert len(aside) == 1 and aside[0].read_text() == text
    assert json.loads(path.read_text()) == good  # written again at once: the file holds what is served


def test_a_fleet_manager_s_run_with_its_own_ids_is_taken_back(tmp_path):
    path = tmp_path / "runs.json"
    run = Run.of_route(4, Route("VDA 5050 order order-7/with slashes", ("node 1/a", "n" * 200)), "vda5050")
    path.write_text(json.dumps([run.as_dict()]))
    history = RunHistory(str(path))
    try:
        assert [r.as_dict() for r in history.all()][0]["waypoints"] == ["node 1/a", "n" * 200]
        assert history.all()[0].state == "interrupted"
    finally:
        history.close()
    assert set_aside(tmp_path) == []


class _Buggy(FakeRobot):
    """A robot whose goal waiting fails once, as a bug of ours would."""

    failures = 1

    def goal_end(self, seq, timeout):
        if self.failures:
            self.failures -= 1
            raise OverflowError("timestamp too large to convert to C _PyTime_t")
        return super().goal_end(seq, timeout)


def test_a_run_whose_worker_fails_ends_failed_saying_so_and_the_next_run_starts(tmp_path, store):
    robot = _Buggy()
    runs = RunExecutor(robot, store, RunHistory(str(tmp_path / "runs.json")))
    try:
        first = runs.start(make_route(None, {"waypoints": ["kitchen"]}, scheduled=False))
        wait_for(lambda: runs.get(first["id"])["state"] == FAILED, message="the run ended failed")
        assert "error of the server's (OverflowError" in runs.get(first["id"])["message"]
        assert any(call[0] == "halt" for call in robot.calls)
        second = runs.start(make_route(None, {"waypoints": ["kitchen"]}, scheduled=False))
        assert second["state"] == "running"
    finally:
        runs.close()
