"""runs.json: what RunHistory writes is the kept runs as JSON, newest first, whatever it reuses to make it."""

import json
import time

from flask_move_server.missions.history import RunHistory
from flask_move_server.missions.route import Route, make_route
from flask_move_server.missions.run import FAILED, SUCCEEDED, Run
from tests.conftest import wait_for


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
