"""The dock is a role, not a name: any waypoint of a map can be its charger, through the real app,
robot and store file (issue 35, item 1). The file on disk is read after each answer; a map whose
file marks no dock and has a place named ``dock`` keeps it as its dock, as before.
"""

import pytest

from flask_move_server.core.errors import WaypointFileError
from flask_move_server.modes.relocalizing import after_start, dock_pose
from flask_move_server.modes.targets import Target
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.waypoints.yaml_format import parse_document


def on_disk(robot_config):
    with open(robot_config.waypoints.file, encoding="utf-8") as f:
        return parse_document(f.read(), "waypoints.yaml")


def dock_of(client):
    marked = [w["name"] for w in client.get("/waypoints").get_json()["waypoints"] if w.get("dock")]
    assert len(marked) <= 1, marked  # one per map
    return marked[0] if marked else None


def test_a_place_in_the_owners_words_becomes_the_dock_and_the_one_named_dock_stops_being_it(client, robot_config):
    assert dock_of(client) == "dock"  # the seed file marks none: the place named dock is, as before
    r = client.put("/waypoints/Ladestation", json={"x": 0.1, "y": 0.2, "yaw": 0.0, "dock": True})
    assert r.status_code == 201 and r.get_json()["waypoint"]["dock"] is True, r.get_json()
    assert dock_of(client) == "Ladestation"
    assert on_disk(robot_config).dock == "Ladestation"
    assert "dock" not in client.get("/waypoints/dock").get_json()  # still a place, no longer the charger

    assert client.put("/waypoints/kitchen", json={"dock": True}).status_code == 200  # where it is
    assert dock_of(client) == "kitchen" and on_disk(robot_config).waypoints["kitchen"].x == 1.23


def test_the_dock_keeps_its_role_under_a_new_name_and_loses_it_when_deleted(client, robot_config):
    assert client.patch("/waypoints/dock", json={"name": "base de carga"}).status_code == 200
    assert dock_of(client) == "base de carga" and on_disk(robot_config).dock == "base de carga"
    assert client.delete("/waypoints/base de carga").status_code == 204
    assert dock_of(client) is None and on_disk(robot_config).dock is None


def test_dock_false_takes_the_role_and_bad_values_change_nothing(client, robot_config):
    client.put("/waypoints/office", json={"dock": True})
    before = open(robot_config.waypoints.file).read()
    for body in ({"dock": "yes"}, {"dock": 1}, {"from": "elsewhere", "dock": True}):
        r = client.put("/waypoints/office", json=body)
        assert r.status_code == 400 and r.get_json()["error"] == "bad_request", body
    r = client.put("/waypoints/nowhere", json={"dock": True})
    assert r.status_code == 404 and r.get_json()["error"] == "unknown_waypoint"
    assert open(robot_config.waypoints.file).read() == before
    assert client.put("/waypoints/office", json={"dock": False}).status_code == 200
    assert dock_of(client) == "dock"  # the place named dock is the dock again: none is marked


def test_the_place_named_dock_cannot_be_unmarked_by_its_name_alone(client, robot_config):
    before = open(robot_config.waypoints.file).read()
    r = client.put("/waypoints/dock", json={"dock": False})
    assert r.status_code == 400 and "rename it, or mark another place" in r.get_json()["message"]
    assert open(robot_config.waypoints.file).read() == before


def test_a_hand_edited_dock_is_read_and_a_bad_one_is_said(tmp_path):
    path = tmp_path / "w.yaml"
    path.write_text("waypoints:\n  Küche: [1.0, 2.0, 0.0]\n  Ladestation: [0.0, 0.5, 1.57]\ndock: Ladestation\n")
    store = WaypointStore(str(path))
    assert store.dock().name == "Ladestation"
    assert dock_pose(str(path))[0] == "Ladestation"
    path.write_text("waypoints:\n  Küche: [1.0, 2.0, 0.0]\ndock: Ladestation\n")  # names none it has
    assert store.dock() is None and store.problem is None  # no dock, the file still serves
    path.write_text("waypoints:\n  Küche: [1.0, 2.0, 0.0]\ndock: [1, 2]\n")
    store.all()
    assert "line 3" in store.problem and "'dock' must name one of the waypoints" in store.problem
    with pytest.raises(WaypointFileError):
        store.put(store.all()[0])  # a broken file refuses changes, as any


def test_after_a_switch_the_robot_is_assumed_on_the_dock_whatever_its_name(tmp_path):
    path = tmp_path / "flat.waypoints.yaml"
    path.write_text("waypoints:\n  Ladestation: [0.5, 0.25, 1.5]\n  dock: [9.0, 9.0, 0.0]\ndock: Ladestation\n")
    published = []
    note, assumed = after_start(Target("navigation", "flat"), lambda _map: str(path), published.append)
    assert assumed == "Ladestation" and (published[0].x, published[0].y) == (0.5, 0.25), note
