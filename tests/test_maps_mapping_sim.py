"""Places marked while mapping go with the map being made, and the configured map stays choosable: a real ``--sim``.

One ``flask-move-server --sim`` process (its own ROS master, real files), driven over HTTP as the
page and robotctl drive it. Mapping twice from the demo map: each save gets exactly the places
marked while making it, the maps saved before keep theirs, and the demo's own places are never
written. The demo map (the one the sim was configured with, outside the maps folder) is listed
under its file's name and can be chosen again, never renamed nor deleted.
"""

import pytest
import requests
import yaml

from tests.conftest import wait_for
from tests.page_browser import PageSim

SWITCH = 60  # s: POST /mode's wait


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("maps_mapping"))
    yield server
    server.close()


def switch(sim, body):
    r = sim.post("/mode", dict(body, wait=SWITCH), timeout=SWITCH + 10)
    assert r.status_code == 200, r.text
    return r.json()


def send(sim, method, path, body=None):
    return requests.request(method, sim.url + path, json=body, headers=sim.headers(), timeout=10)


def names(sim):
    return [w["name"] for w in sim.get("/waypoints").json()["waypoints"]]


def mark(sim, name, x, y):
    r = send(sim, "PUT", "/waypoints/" + name, {"x": x, "y": y, "yaw": 0.0})
    assert r.status_code == 201, r.text


def saved_places(sim, name):
    path = sim.folder / "maps" / (name + ".waypoints.yaml")
    return sorted(yaml.safe_load(path.read_text())["waypoints"]) if path.exists() else []


def save(sim, name, then=True):
    body = {"name": name, "then": "navigation"} if then else {"name": name}
    r = sim.post("/maps", body, timeout=30)
    assert r.status_code == 201, r.text
    if then:
        wait_for(lambda: running(sim, "navigation", name), timeout=SWITCH, message="navigation on " + name)
    return r.json()


def running(sim, mode, map_name):
    now = sim.get("/mode").json()
    return (now["mode"], now["map"], now["state"]) == (mode, map_name, "running")


def test_the_configured_map_is_listed_described_drawn_and_never_renamed_or_deleted(sim):
    listed = sim.get("/maps").json()
    demo = listed["maps"][0]
    assert (demo["name"], demo["source"], demo["waypoints"]) == ("demo", "configured", 5)
    assert demo["width"] > 0 and demo["resolution"] > 0
    assert listed["active"] == "demo"  # --sim starts navigating on it: /mode and the list name it alike
    assert sim.get("/mode").json()["map"] == "demo"
    assert sim.get("/maps/demo").json()["active"] is True
    image = sim.get("/maps/demo/image")
    assert image.status_code == 200 and image.content.startswith(b"\x89PNG")
    for r in (send(sim, "DELETE", "/maps/demo"), send(sim, "PATCH", "/maps/demo", {"name": "home"})):
        assert r.status_code == 409 and r.json()["error"] == "map_configured", r.text
        assert "configured" in r.json()["message"]
    assert sim.get("/maps/demo").status_code == 200


def test_robotctl_lists_the_configured_map_and_says_why_it_cannot_remove_it(sim, capsys):
    from flask_move_server.robotctl import cli as robotctl

    assert robotctl.main(["--url", sim.url, "map", "list"]) == 0
    demo = [line for line in capsys.readouterr().out.splitlines() if " demo " in line]
    assert len(demo) == 1 and demo[0].startswith("*") and demo[0].endswith("(configured)")
    assert robotctl.main(["--url", sim.url, "map", "rm", "demo"]) != 0
    assert "configured" in capsys.readouterr().err


def test_marks_while_mapping_go_with_the_map_made_and_the_configured_map_is_chosen_again(sim):
    demo_places = sim.waypoints.read_text()
    switch(sim, {"mode": "mapping"})
    assert names(sim) == []  # the demo's places are not this map's
    mark(sim, "sofa", 1.0, 0.5)
    mark(sim, "desk", 2.0, 0.5)
    save(sim, "first")
    assert saved_places(sim, "first") == ["desk", "sofa"]
    assert names(sim) == ["sofa", "desk"]  # navigating on it: its places, as marked

    switch(sim, {"mode": "mapping"})
    assert names(sim) == []  # a new map: a new frame, no places yet
    mark(sim, "hall", 0.5, 0.0)
    listed = save(sim, "second")
    assert listed["map"]["waypoints"] == 1
    assert saved_places(sim, "second") == ["hall"]
    assert saved_places(sim, "first") == ["desk", "sofa"]  # unchanged
    assert sim.waypoints.read_text() == demo_places  # the demo's own places: never written while mapping

    mode = switch(sim, {"mode": "navigation", "map": "demo"})
    assert mode["map"] == "demo" and mode["state"] == "running"
    assert names(sim) == ["kitchen", "office", "bedroom", "sofa", "dock"]  # the demo's own places again
    assert sim.get("/maps").json()["active"] == "demo"


def test_no_map_may_be_saved_under_the_configured_maps_name(sim):
    switch(sim, {"mode": "mapping"})
    r = sim.post("/maps", {"name": "Demo"}, timeout=30)
    assert r.status_code == 409 and r.json()["error"] == "map_exists" and "robot's own map" in r.json()["message"]
    assert not (sim.folder / "maps" / "Demo.yaml").exists()
    switch(sim, {"mode": "navigation", "map": "demo"})


def test_a_restart_while_mapping_starts_a_new_map_with_no_places(tmp_path):
    """Mapping does not survive a restart (SLAM starts a new map, in a new frame): its marks go with it."""
    first = PageSim(tmp_path)
    try:
        switch(first, {"mode": "mapping"})
        mark(first, "desk", 1.0, 0.5)
    finally:
        first.close()
    again = PageSim(tmp_path)
    try:
        wait_for(lambda: running(again, "mapping", None), timeout=SWITCH, message="mapping again after the restart")
        assert names(again) == []
        assert "desk" not in again.waypoints.read_text()  # and the demo's own places were never touched
    finally:
        again.close()
