"""runs.json: what RunHistory writes is the kept runs as JSON, newest first, whatever it reuses to make it."""

import json

from flask_move_server.missions.history import RunHistory
from flask_move_server.missions.route import Route
from flask_move_server.missions.run import FAILED, SUCCEEDED, Run


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
