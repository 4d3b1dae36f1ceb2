"""A map keeps a bounded number of waypoints and routes, and never a file it cannot read back (issue 34, item 4).

Before: ``PUT /routes`` was taken past the 4 Mi characters the reader takes, so after the next
restart the robot had no waypoints and no routes, and its ``.bak`` was too big to put back. Real
files throughout: what is refused leaves the bytes on disk as they were, and a fresh store (the
server after a restart) reads back everything that was acknowledged.
"""

import pytest

from flask_move_server.core.errors import MapFull, WaypointFileError
from flask_move_server.missions.executor import RunExecutor
from flask_move_server.missions.history import RunHistory
from flask_move_server.missions.route import make_route
from flask_move_server.waypoints import locked_file, make_waypoint
from flask_move_server.waypoints.store import MAX_ROUTES, MAX_SAVED, MAX_WAYPOINTS, WaypointStore
from flask_move_server.waypoints.yaml_format import dump
from flask_move_server.web import create_app
from tests.fake_robot import FakeRobot

LONG = "a" * 60  # a long but valid name: routes of 200 such stops make a big file quickly


def places(n, prefix="p"):
    return [make_waypoint("{}{:04d}".format(prefix, i), i * 0.01, 0.0, 0.0) for i in range(n)]


def routes(n, stops, width=200):
    return [make_route("r{:04d}".format(i), {"waypoints": [stops[(i + j) % len(stops)] for j in range(width)]})
            for i in range(n)]


def written(path, waypoints, routes_=()):
    path.write_text(dump(waypoints, routes_))
    return path.read_bytes()


def test_the_route_past_the_cap_is_refused_naming_it_and_the_file_stays_as_it_was(tmp_path):
    path = tmp_path / "waypoints.yaml"
    stops = places(3)
    written(path, stops, routes(MAX_ROUTES - 1, [w.name for w in stops], width=3))
    store = WaypointStore(str(path))
    assert store.put_route(make_route("the last one", {"waypoints": ["p0000"]})) is True
    before = path.read_bytes()
    with pytest.raises(MapFull) as caught:
        store.put_route(make_route("one too many", {"waypoints": ["p0001"]}))
    assert "at most {} routes".format(MAX_ROUTES) in str(caught.value) and "Nothing was changed" in str(caught.value)
    assert path.read_bytes() == before
    store.put_route(make_route("the last one", {"waypoints": ["p0002"]}))  # replacing one adds nothing
    after_restart = WaypointStore(str(path))
    assert len(after_restart.routes()) == MAX_ROUTES and after_restart.problem is None
    assert after_restart.get_route("the last one").waypoints == ("p0002",)


def test_the_waypoint_past_the_cap_is_refused_but_an_over_full_hand_edited_map_still_shrinks(tmp_path):
    path = tmp_path / "waypoints.yaml"
    before = written(path, places(MAX_WAYPOINTS + 5))  # written by hand: it loads, as it always did
    store = WaypointStore(str(path))
    assert len(store.all()) == MAX_WAYPOINTS + 5 and store.problem is None
    with pytest.raises(MapFull) as caught:
        store.put(make_waypoint("Küche", 1.0, 2.0, 0.0))
    assert "at most {} waypoints".format(MAX_WAYPOINTS) in str(caught.value)
    assert path.read_bytes() == before
    store.put(make_waypoint("p0000", 5.0, 5.0, 0.0))  # moving one that is there adds nothing
    store.delete("p0001")
    store.rename("p0002", "Küche")
    assert len(WaypointStore(str(path)).all()) == MAX_WAYPOINTS + 4


def test_a_change_that_would_make_the_file_too_big_is_refused_and_deleting_still_works(tmp_path):
    path = tmp_path / "waypoints.yaml"
    stops = places(200, LONG)
    many = routes(36, [w.name for w in stops])  # long routes of long names: the file's size binds before the count
    written(path, stops, many)
    store = WaypointStore(str(path))
    store.put_route(many[0])  # a route put again as it was: the same size, taken
    before = path.read_bytes()
    assert len(before) < MAX_SAVED
    with pytest.raises(MapFull) as caught:
        for more in routes(5, [w.name for w in stops]):
            store.put_route(make_route("more " + more.name, {"waypoints": list(more.waypoints)}))
    message = str(caught.value)
    assert "holds at most {} (its waypoints and routes)".format(MAX_SAVED) in message and "Nothing" in message
    before = path.read_bytes()
    store.delete_route("r0000")
    after_restart = WaypointStore(str(path))
    assert len(before) <= MAX_SAVED and len(after_restart.routes()) == len(store.routes()) and \
        after_restart.problem is None


def test_an_over_big_hand_edited_map_still_loads_and_shrinks(tmp_path):
    path = tmp_path / "waypoints.yaml"
    stops = places(200, LONG)
    before = written(path, stops, routes(44, [w.name for w in stops]))
    assert len(before) > MAX_SAVED  # only a hand edit gets here
    store = WaypointStore(str(path))
    with pytest.raises(MapFull):
        store.put(make_waypoint("Küche", 1.0, 2.0, 0.0))
    assert path.read_bytes() == before
    store.delete_route("r0000")
    assert len(WaypointStore(str(path)).routes()) == 43


def test_no_writer_leaves_a_file_the_reader_refuses(tmp_path):
    path = tmp_path / "mode.json"
    path.write_text("{}\n")
    with pytest.raises(WaypointFileError, match="nothing was written"):
        locked_file.atomic_write(str(path), "x" * (locked_file.MAX_TEXT + 1))
    assert path.read_text() == "{}\n" and sorted(p.name for p in tmp_path.iterdir()) == ["mode.json"]
    locked_file.atomic_write(str(path), "x" * locked_file.MAX_TEXT)  # what the reader takes is written
    assert len(locked_file.read(str(path))) == locked_file.MAX_TEXT


def test_over_http_the_owner_is_told_409_map_full_and_the_routes_stay(robot_config, store, tmp_path):
    robot = FakeRobot()
    with open(robot_config.waypoints.file, "w") as f:
        f.write(dump(store.all(), routes(MAX_ROUTES, ["kitchen"], width=1)))
    runs = RunExecutor(robot, store, RunHistory(str(tmp_path / "runs.json")))
    try:
        client = create_app(robot_config, robot, store, runs=runs).test_client()
        r = client.put("/routes/Abendrunde", json={"waypoints": ["kitchen"]})
        assert r.status_code == 409 and r.get_json()["error"] == "map_full"
        assert "at most {} routes".format(MAX_ROUTES) in r.get_json()["message"]
        assert len(client.get("/routes").get_json()["routes"]) == MAX_ROUTES
        assert client.put("/waypoints/Küche", json={"x": 1, "y": 2, "yaw": 0}).status_code == 201  # routes full only
    finally:
        runs.close()
