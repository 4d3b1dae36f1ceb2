"""No-go zones and virtual walls in the demo flat: ``flask-move-server --sim``, one real server for the module.

The simulated move_base obeys the zones only as the real one would (``zones/costmap_rules.py`` on
the shipped costmap files): it hears the mask the server publishes on ``keepout_map``, the same
latched message a real costmap's ``keepout_layer`` hears. A goal whose straight way crosses a
no-go zone arrives without the robot's true pose ever inside it; a wall across the bedroom's
door makes the bedroom unreachable, and switching it off makes it reachable again, no restart; a
goal inside a zone is refused 409 ``in_zone`` with nothing sent to move_base; the mask on the
topic is the zones' cells on the map's own header; a zone switched on around the robot is left
out of the mask until the robot has driven out of it.
"""

import json
import os
import subprocess
import sys
import threading
import time

import pytest

from flask_move_server.zones import distance, make_zone
from flask_move_server.zones.mask import cells
from tests.conftest import ROOT, stop_process, wait_for
from tests.test_sim_e2e import SimServer

CAT_CORNER = [[1.5, 0.0], [2.5, 0.0], [2.5, 1.3], [1.5, 1.3]]  # across the way from the dock to the kitchen's door
BEDROOM_DOOR = [[4.8, 2.5], [6.1, 2.5]]  # the bedroom's one door: the wall y 2.5 has it at x 5.0..5.9
MAP = {"width": 260, "height": 180, "resolution": 0.05, "origin": (-2.5, -2.5)}  # config/maps/demo.yaml


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = SimServer(tmp_path_factory.mktemp("zones"))
    yield server
    stop_process(server.proc)


@pytest.fixture(autouse=True)
def no_zones(sim):
    yield
    zones = sim.get("/zones").json()["zones"]
    for zone in zones:
        assert sim.delete("/zones/" + zone["name"]).status_code == 204
    if zones:
        time.sleep(1.0)  # a change reaches the costmaps within a second


def _truth(sim):
    return sim.status()["sim"]["true_pose"]


class Track:
    """The robot's true pose, sampled every 50 ms while a goal runs."""

    def __init__(self, sim):
        self.poses, self._stop = [], threading.Event()
        self._thread = threading.Thread(target=self._sample, args=(sim,), daemon=True)

    def _sample(self, sim):
        while not self._stop.wait(0.05):
            self.poses.append(_truth(sim))

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()


def _goal(sim, name, wait=120):
    return sim.post("/goto", {"name": name, "wait": wait}, timeout=wait + 10)


def _put(sim, name, body):
    r = sim.put("/zones/" + name, body)
    assert r.status_code in (200, 201), r.text
    return r.json()["zone"]


def test_a_goal_whose_straight_way_crosses_a_no_go_zone_drives_around_it(sim):
    assert _goal(sim, "dock").status_code == 200
    _put(sim, "Katzenecke", {"kind": "keepout", "polygon": CAT_CORNER})
    zone = make_zone("Katzenecke", {"kind": "keepout", "polygon": CAT_CORNER})
    time.sleep(1.0)  # the mask reaches the costmaps within a second
    with Track(sim) as track:
        r = _goal(sim, "kitchen")
    assert r.status_code == 200, r.text
    assert track.poses, "no poses sampled"
    nearest = min(distance(zone, p["x"], p["y"]) for p in track.poses)
    assert nearest > 0.1, "the robot's centre came {:.2f} m from the zone".format(nearest)


def test_a_wall_across_the_door_keeps_the_bedroom_unreachable_until_it_is_switched_off(sim):
    assert _goal(sim, "sofa").status_code == 200
    _put(sim, "Schlafzimmertür", {"kind": "wall", "line": BEDROOM_DOOR})
    time.sleep(1.0)
    r = _goal(sim, "bedroom", wait=60)
    assert r.status_code == 409 and r.json()["error"] == "navigation_failed", r.text
    assert sim.status()["navigation"]["state"] == "aborted"
    r = sim.patch("/zones/Schlafzimmertür", {"enabled": False})
    assert r.status_code == 200 and r.json()["zone"]["enabled"] is False, r.text
    time.sleep(1.0)
    assert _goal(sim, "bedroom").status_code == 200


def test_a_goal_inside_a_zone_is_refused_before_move_base_hears_of_it(sim):
    _put(sim, "Katzenecke", {"kind": "keepout", "polygon": CAT_CORNER})
    before = sim.status()["navigation"]
    r = sim.post("/goto", {"x": 2.0, "y": 0.6, "yaw": 0.0})
    assert r.status_code == 409 and r.json()["error"] == "in_zone", r.text
    assert "Katzenecke" in r.json()["message"]
    assert sim.status()["navigation"].get("goal_id") == before.get("goal_id")
    r = sim.put("/waypoints/Napf", {"x": 2.0, "y": 0.6, "yaw": 0.0})
    assert r.status_code == 201, r.text
    r = sim.post("/goto", {"name": "Napf"})
    assert r.status_code == 409 and r.json()["error"] == "in_zone" and "Napf" in r.json()["message"], r.text
    runs = sim.get("/runs").json()["runs"]
    r = sim.post("/runs", {"waypoints": ["sofa", "Napf"]})  # refused before its first stop, not at the second
    assert r.status_code == 409 and r.json()["error"] == "in_zone" and "Napf" in r.json()["message"], r.text
    assert sim.get("/runs").json()["runs"] == runs
    assert sim.status()["navigation"].get("goal_id") == before.get("goal_id")
    assert sim.delete("/waypoints/Napf").status_code == 204


def _masks(sim, count):
    env = dict(os.environ, ROS_MASTER_URI=sim.master_uri, ROS_IP="127.0.0.1", PYTHONPATH=ROOT)
    return subprocess.Popen([sys.executable, "-m", "tests.mask_reader", str(count)], stdout=subprocess.PIPE,
                            text=True, env=env, cwd=ROOT)


def test_the_mask_is_the_zones_cells_on_the_map_s_own_header(sim):
    _put(sim, "Katzenecke", {"kind": "keepout", "polygon": CAT_CORNER})
    _put(sim, "Tür", {"kind": "wall", "line": BEDROOM_DOOR})
    time.sleep(0.6)
    reader = _masks(sim, 1)
    try:
        heard = json.loads(reader.stdout.readline())
    finally:
        stop_process(reader)
    zones = [make_zone("Katzenecke", {"kind": "keepout", "polygon": CAT_CORNER}),
             make_zone("Tür", {"kind": "wall", "line": BEDROOM_DOOR})]
    expected = cells(zones, MAP["width"], MAP["height"], MAP["resolution"], *MAP["origin"])
    mask, map_ = heard["mask"], heard["map"]
    assert mask["frame"] == map_["frame"] == "map"
    assert mask["info"] == map_["info"], "the mask's size, resolution or origin differ from the map's"
    assert mask["cells"] == MAP["width"] * MAP["height"] and mask["other"] == [255]  # -1: no zone
    assert mask["lethal"] == [i for i, v in enumerate(expected) if v == 100]
    assert len(mask["lethal"]) > 400


def test_a_zone_switched_on_around_the_robot_waits_until_it_has_left(sim):
    assert _goal(sim, "sofa").status_code == 200
    here = _truth(sim)
    around = [[here["x"] - 0.5, here["y"] - 0.5], [here["x"] + 0.5, here["y"] - 0.5],
              [here["x"] + 0.5, here["y"] + 0.5], [here["x"] - 0.5, here["y"] + 0.5]]
    zone = _put(sim, "Teppich", {"kind": "keepout", "polygon": around})
    wait_for(lambda: sim.get("/zones/Teppich").json().get("waiting") is True, timeout=5,
             message="the zone to wait for the robot to leave")
    assert zone["enabled"] is True
    assert _goal(sim, "dock").status_code == 200  # out of it: the plan starts inside, where the mask left it free
    wait_for(lambda: sim.get("/zones/Teppich").json().get("waiting") is False, timeout=5,
             message="the zone to keep the robot out again")
    r = sim.post("/goto", {"name": "sofa"})
    assert r.status_code == 409 and r.json()["error"] == "in_zone", r.text


def test_robotctl_adds_lists_switches_and_removes_a_zone(sim, capsys):
    from flask_move_server.robotctl import cli

    url = ["--url", sim.url]
    assert cli.main(url + ["zone", "add", "Katzenecke", "--keepout", "1.5,0", "2.5,0", "2.5,1.3", "1.5,1.3"]) == 0
    assert capsys.readouterr().out.strip() == "saved: Katzenecke  keep out 1.5,0 2.5,0 2.5,1.3 1.5,1.3  (on)"
    assert cli.main(url + ["zone", "add", "Treppe", "--wall", "4.8,2.5", "6.1,2.5", "--disabled"]) == 0
    assert cli.main(url + ["zone", "disable", "Katzenecke"]) == 0
    capsys.readouterr()
    assert cli.main(url + ["zone", "list"]) == 0
    assert capsys.readouterr().out.splitlines() == ["Katzenecke  keep out 1.5,0 2.5,0 2.5,1.3 1.5,1.3  (off)",
                                                     "Treppe  wall 4.8,2.5 6.1,2.5  (off)"]
    assert cli.main(url + ["zone", "add", "Knoten", "--keepout", "0,3", "1,4", "1,3", "0,4"]) == 1
    assert "crosses itself" in capsys.readouterr().err
    assert cli.main(url + ["zone", "rm", "Treppe"]) == 0
    assert cli.main(url + ["zone", "enable", "Treppe"]) == 5
    assert "No zone named" in capsys.readouterr().err
    assert [z["name"] for z in sim.get("/zones").json()["zones"]] == ["Katzenecke"]
