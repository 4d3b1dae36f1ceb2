"""``PATCH /waypoints/<name>``: a rename in one save, through the real app, robot and store file.

Renaming used to be a PUT of the new name then a DELETE of the old one: a failure between the
two left the place twice. Here the file on disk is read after each answer.
"""

from flask_move_server.waypoints.yaml_format import parse


def on_disk(robot_config):
    with open(robot_config.waypoints.file) as f:
        return {name: [w.x, w.y, w.yaw] for name, w in parse(f.read(), "waypoints.yaml").items()}


def names_on_disk(robot_config):
    return list(on_disk(robot_config))


def test_a_rename_keeps_the_place_and_its_spot_in_the_file(client, robot_config):
    r = client.patch("/waypoints/office", json={"name": "study room"})
    assert r.status_code == 200, r.get_json()
    assert r.get_json() == {"status": "ok", "waypoint": {"name": "study room", "x": 5.67, "y": 2.34, "yaw": -1.57}}
    assert names_on_disk(robot_config) == ["kitchen", "study room", "dock"]
    assert client.get("/waypoints/office").status_code == 404
    assert client.get("/waypoints/study room").get_json()["x"] == 5.67


def test_onto_another_name_is_409_unless_asked_to_overwrite(client, robot_config):
    before = on_disk(robot_config)
    r = client.patch("/waypoints/office", json={"name": "kitchen"})
    assert r.status_code == 409
    body = r.get_json()
    assert body["error"] == "waypoint_exists" and "kitchen" in body["message"]
    assert on_disk(robot_config) == before, "a refused rename changes nothing"

    r = client.patch("/waypoints/office", json={"name": "kitchen", "overwrite": True})
    assert r.status_code == 200
    assert on_disk(robot_config) == {"kitchen": [5.67, 2.34, -1.57], "dock": [0.0, 0.0, 0.0]}


def test_unknown_is_404_with_suggestions(client, robot_config):
    before = on_disk(robot_config)
    r = client.patch("/waypoints/ofice", json={"name": "study"})
    assert r.status_code == 404
    assert r.get_json()["error"] == "unknown_waypoint" and "office" in r.get_json()["suggestions"]
    assert on_disk(robot_config) == before


def test_bad_names_and_bodies_are_400_and_change_nothing(client, robot_config):
    before = on_disk(robot_config)
    for body in ({"name": "a/b"}, {"name": ""}, {"name": "x" * 65}, {"name": ".."}):
        r = client.patch("/waypoints/office", json=body)
        assert (r.status_code, r.get_json()["error"]) == (400, "bad_waypoint"), body
    for body in ({}, {"name": 5}, {"name": "study", "overwrite": "yes"}, {"name": "study", "x": 1}):
        r = client.patch("/waypoints/office", json=body)
        assert (r.status_code, r.get_json()["error"]) == (400, "bad_request"), body
        assert r.get_json()["message"]
    assert on_disk(robot_config) == before


def test_renaming_to_its_own_name_changes_nothing(client, robot_config):
    before = on_disk(robot_config)
    r = client.patch("/waypoints/dock", json={"name": "dock"})
    assert r.status_code == 200 and r.get_json()["waypoint"]["name"] == "dock"
    assert on_disk(robot_config) == before
