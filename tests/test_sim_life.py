"""A robot's whole life in the simulation, over HTTP as a user's curl or phone does it.

``flask-move-server --sim`` (own master, speed factor): start mapping (the robot knows nothing),
drive it into unknown space with goals until the flat is mapped, save the map and switch to
navigation on it in one request, mark a place, relocalize at the dock, go to the place, switch
maps and back to idle; every answer the documented shape. Real server process, real ROS, the
sim's SLAM and move_base stand-in.
"""

import math
import struct
import zlib

import pytest
import requests

from tests.conftest import stop_process, wait_for
from tests.test_sim_e2e import SimServer

# Goals into the unknown: to the kitchen and back the way it came (map frame == world), all the later
# tests drive; the straight way back to the dock got stuck once under load.
FIRST_MAP = {}  # the map as mapping began, compared after driving (the tests run in order)
EXPLORE = [(3.0, 0.5), (8.4, 0.9), (3.0, 0.5), (0.0, 0.0)]


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = SimServer(tmp_path_factory.mktemp("life"))
    yield server
    stop_process(server.proc)


def _put(sim, path, body):
    return requests.put(sim.url + path, json=body, timeout=10)


def _mode(sim):
    return sim.get("/mode").json()


def _switch(sim, body, wait=60):
    body = dict(body, wait=wait)
    answer = sim.post("/mode", body, timeout=90)
    assert answer.status_code == 200, answer.text
    assert answer.json()["state"] == "running"
    return answer.json()


def _go(sim, **goal):
    answer = sim.post("/goto", dict(goal, wait=120), timeout=150)
    assert answer.status_code == 200, answer.text
    return answer.json()


def test_the_demo_starts_navigating_on_its_own_map(sim):
    mode = wait_for(lambda: _mode(sim)["state"] != "starting" and _mode(sim), timeout=30,
                    message="the demo's own map to be running")
    assert (mode["mode"], mode["state"]) == ("navigation", "running")


def _known_cells(sim):
    """How many pixels of ``/map/image`` are free (white) or occupied (black), not unknown (grey)."""
    png = sim.get("/map/image").content
    width, height = struct.unpack(">II", png[16:24])
    chunks, at = [], 8
    while at < len(png):
        length, kind = struct.unpack(">I4s", png[at:at + 8])
        if kind == b"IDAT":
            chunks.append(png[at + 8:at + 8 + length])
        at += 12 + length
    rows = zlib.decompress(b"".join(chunks))
    assert all(rows[r * (width + 1)] == 0 for r in range(height))  # filter "none" on every row
    return sum(1 for i, v in enumerate(rows) if i % (width + 1) and v in (0, 254))


def test_mapping_from_scratch_starts_from_what_the_laser_sees(sim):
    _switch(sim, {"mode": "mapping"})
    wait_for(lambda: sim.get("/map").status_code == 200, timeout=30, message="a /map from the sim's SLAM")
    FIRST_MAP.update(meta=sim.get("/map").json(), known=_known_cells(sim))
    assert sim.get("/mode").json()["mode"] == "mapping"


def test_driving_into_the_unknown_grows_the_map(sim):
    for x, y in EXPLORE:
        _go(sim, x=x, y=y, yaw=0.0)
    after = sim.get("/map").json()
    assert after["version"] != FIRST_MAP["meta"]["version"]
    assert _known_cells(sim) > 1.5 * FIRST_MAP["known"]


def test_saving_outside_mapping_is_refused_and_saving_in_mapping_switches_to_navigation(sim):
    answer = sim.post("/maps", {"name": "flat", "then": "navigation"})
    assert answer.status_code == 201, answer.text
    wait_for(lambda: _mode(sim)["state"] == "running", timeout=60, message="navigation on the saved map")
    mode = _mode(sim)
    assert (mode["mode"], mode["map"]) == ("navigation", "flat")
    listed = sim.get("/maps").json()
    assert [m["name"] for m in listed["maps"] if m["source"] == "saved"] == ["flat"] and listed["active"] == "flat"
    refused = sim.post("/maps", {"name": "other"})
    assert refused.status_code == 409 and refused.json()["error"] == "wrong_mode"


def test_marking_relocalizing_and_going_on_the_new_map(sim):
    assert _put(sim, "/waypoints/dock", {"x": 0.0, "y": 0.0, "yaw": 0.0}).status_code in (200, 201)
    assert _put(sim, "/waypoints/kitchen", {"x": 8.4, "y": 0.9, "yaw": 0.0}).status_code in (200, 201)
    assert sim.post("/pose", {"name": "dock"}).status_code == 200
    wait_for(lambda: math.hypot(sim.pose()["x"], sim.pose()["y"]) < 0.2, timeout=10, message="robot at the dock")
    done = _go(sim, name="kitchen")
    assert done["navigation"]["state"] == "succeeded"


def test_back_to_idle_then_the_map_again(sim):
    _switch(sim, {"mode": "idle"})
    assert sim.get("/map").status_code == 404
    r = sim.post("/goto", {"name": "kitchen"})
    assert r.status_code == 409 and r.json()["error"] == "wrong_mode", r.text  # idle: the owner's choice
    _switch(sim, {"mode": "navigation", "map": "flat"})
    assert sim.get("/waypoints/kitchen").status_code == 200
