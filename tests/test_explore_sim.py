"""Exploring a flat from nothing, in the simulation: ``POST /explore`` on a real ``--sim`` server.

Each world is a real ``flask-move-server --sim`` process (its own ROS master) whose simulated world
is one of ``tests/explore_worlds.py`` or the demo flat. The robot knows nothing of it: the explorer
switches to mapping, drives to frontiers of the growing SLAM map through the move_base stand-in
(which obeys the robot's own DWA and move_base files), comes back, saves the map and navigates on
it. What a user would check is checked against the world's own map: how much of the floor a robot
of this size can reach is known in the saved map (at least 95 %), where the robot stands at the end
(within 0.3 m of where it began), the mode. A room behind a gap narrower than the robot is reported
unreachable, not looped on. ``/stop`` and the e-stop end it at once and the robot stands.
"""

import math
import os
import time

import numpy as np
import pytest

from flask_move_server.explore import frontiers
from flask_move_server.maps import mapfile
from tests import explore_worlds
from tests.conftest import ROOT, wait_for
from tests.page_browser import PageSim

RADIUS = 0.15  # sim.robot_radius's default: what the explorer and the move_base stand-in keep from walls
EXPLORE_WAIT = 420  # s: the longest world at speed 4 takes under 2 minutes here
TEST_WAIT = EXPLORE_WAIT + 60  # pytest's limit for one exploration: past EXPLORE_WAIT, so finished() says why
DEMO = os.path.join(ROOT, "config", "maps", "demo.yaml")


def explore(sim, body, expect=202):
    r = sim.post("/explore", body, timeout=30)
    assert r.status_code == expect, r.text
    return r.json()


def exploration(sim):
    return sim.get("/explore").json()["exploration"]


def finished(sim, timeout=EXPLORE_WAIT):
    """The exploration once it ended (done, failed, canceled or stuck); if it does not, what it was
    doing and what the server logged of it."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        now = exploration(sim)
        if now["state"] in ("done", "failed", "canceled", "stuck"):
            return now
        time.sleep(1.0)
    told = [line.rstrip() for line in sim.lines if "explor" in line or "goal" in line][-40:]
    raise AssertionError("the exploration did not end in {} s: {}\nstatus: {}\nlog:\n{}".format(
        timeout, now, sim.status(), "\n".join(told)))


def true_pose(sim):
    return sim.status()["sim"]["true_pose"]


def coverage(world_yaml, saved_yaml, start=(0.0, 0.0)):
    """The share of the floor a robot of RADIUS can reach from ``start`` that the saved map knows as free."""
    truth, saved = mapfile.load(world_yaml), mapfile.load(saved_yaml)
    reach = frontiers.reachable_free(truth, start, RADIUS)
    rows, cols = np.nonzero(reach)
    xs = truth.origin_x + (cols + 0.5) * truth.resolution
    ys = truth.origin_y + (rows + 0.5) * truth.resolution
    scols = np.floor((xs - saved.origin_x) / saved.resolution).astype(int)
    srows = np.floor((ys - saved.origin_y) / saved.resolution).astype(int)
    inside = (scols >= 0) & (scols < saved.width) & (srows >= 0) & (srows < saved.height)
    known = frontiers.as_array(saved)
    free = np.zeros(len(xs), dtype=bool)
    free[inside] = (known[srows[inside], scols[inside]] >= 0) & (known[srows[inside], scols[inside]] < 50)
    return free.sum() / float(len(xs))


def assert_explored(sim, world_yaml, name, start=(0.0, 0.0)):
    done = finished(sim)
    assert done["state"] == "done", done
    assert done["map"] == name
    wait_for(lambda: sim.get("/mode").json()["state"] == "running", timeout=60, message="navigation on the map")
    mode = sim.get("/mode").json()
    assert (mode["mode"], mode["map"]) == ("navigation", name), mode
    here = true_pose(sim)
    assert math.hypot(here["x"] - start[0], here["y"] - start[1]) <= 0.3, (here, done["message"])
    share = coverage(world_yaml, str(sim.folder / "maps" / (name + ".yaml")), start)
    assert share >= 0.95, "only {:.1%} of the reachable floor is in the saved map".format(share)
    return done


@pytest.fixture(scope="module")
def worlds(tmp_path_factory):
    return tmp_path_factory.mktemp("worlds")


@pytest.mark.parametrize("world", ["hall", "rooms", "dead_end"])
def test_a_world_is_explored_from_nothing_saved_and_navigated_on(world, worlds, tmp_path):
    path = explore_worlds.write(worlds, world)
    sim = PageSim(tmp_path, world=path)
    try:
        name = "mapped-" + world  # not the world's own name: the map the sim was configured with has it
        started = explore(sim, {"save_as": name})["exploration"]
        assert started["state"] == "starting" and started["save_as"] == name
        done = assert_explored(sim, path, name)
        assert done["goals"] >= 1 and done["frontiers"] == 0
    finally:
        sim.close()


def test_a_room_behind_a_gap_narrower_than_the_robot_is_unreachable_not_looped_on(worlds, tmp_path):
    path = explore_worlds.write(worlds, "narrow")
    sim = PageSim(tmp_path, world=path)
    try:
        explore(sim, {"save_as": "mapped-narrow"})
        done = assert_explored(sim, path, "mapped-narrow")
        assert done["unreachable"] >= 1, done
        assert "too narrow" in done["message"]
        assert done["goals"] <= 15, "it kept sending goals at the gap: {}".format(done)
    finally:
        sim.close()


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    sim = PageSim(tmp_path_factory.mktemp("explore_demo"))
    yield sim
    sim.close()


def test_stop_ends_exploring_at_once_the_robot_stands_and_the_map_stays_unsaved(demo):
    explore(demo, {"save_as": "halfway"})
    wait_for(lambda: exploration(demo)["goals"] >= 1 and exploration(demo)["state"] == "exploring", timeout=60,
             message="a first frontier goal")
    time.sleep(1.0)  # under way
    r = demo.post("/stop")
    assert r.status_code == 200, r.text
    ended = exploration(demo)
    assert ended["state"] == "canceled" and "Stopped" in ended["message"], ended
    assert ended["map"] is None
    assert_stands(demo)
    assert demo.get("/mode").json()["mode"] == "mapping"
    assert not (demo.folder / "maps" / "halfway.yaml").exists()


def test_the_estop_ends_exploring_and_the_robot_stands(demo):
    explore(demo, {"save_as": "halfway", "overwrite": True})
    wait_for(lambda: exploration(demo)["goals"] >= 1, timeout=60, message="a first frontier goal")
    assert demo.post("/estop").status_code == 200
    try:
        ended = exploration(demo)
        assert ended["state"] == "canceled" and "e-stop" in ended["message"], ended
        assert_stands(demo)
        refused = explore(demo, {"save_as": "later"}, expect=409)
        assert refused["error"] == "estop_latched"
    finally:
        assert demo.post("/estop/release").status_code == 200


@pytest.mark.timeout(TEST_WAIT)  # the whole flat: ~50 s alone, past pytest's 120 s beside a busy CI's other worker
def test_the_demo_flat_is_explored_and_a_taken_name_is_refused_before_the_robot_moves(demo):
    wait_for(lambda: not demo.status()["estop"]["latched"], timeout=10, message="the e-stop released")
    start = true_pose(demo)
    explore(demo, {"save_as": "flat"})
    assert_explored(demo, DEMO, "flat", start=(start["x"], start["y"]))
    before = true_pose(demo)
    refused = explore(demo, {"save_as": "flat"}, expect=409)
    assert refused["error"] == "map_exists"
    assert exploration(demo)["state"] == "done"  # the last one, untouched
    time.sleep(1.0)
    after = true_pose(demo)
    assert math.hypot(after["x"] - before["x"], after["y"] - before["y"]) < 0.01
    assert demo.get("/mode").json()["mode"] == "navigation"


BEDROOM = (3.55, 2.55, 10.0, 6.0)  # x0, y0, x1, y1 (sim/demo_map.py): its one door at x 5.0..5.9 on y 2.5
BEDROOM_DOOR = [[4.8, 2.5], [6.1, 2.5]]


@pytest.mark.timeout(TEST_WAIT)
def test_a_wall_drawn_while_mapping_keeps_exploring_out_of_the_room_behind_it_and_is_saved_with_the_map(demo):
    r = demo.post("/mode", {"mode": "mapping"}, timeout=30)
    assert r.status_code in (200, 202), r.text
    wait_for(lambda: demo.get("/mode").json()["state"] == "running", timeout=60, message="mapping")
    r = demo.put("/zones/Schlafzimmertür", {"kind": "wall", "line": BEDROOM_DOOR})
    assert r.status_code == 201, r.text
    explore(demo, {"save_as": "walled"})
    deepest, done = None, None
    deadline = time.monotonic() + EXPLORE_WAIT
    while done is None and time.monotonic() < deadline:  # where the robot went, looked at each half second
        pose = true_pose(demo)
        if BEDROOM[0] < pose["x"] < BEDROOM[2]:
            deepest = max(deepest or pose["y"], pose["y"])
        now = exploration(demo)
        done = now if now["state"] in ("done", "failed", "canceled", "stuck") else None
        time.sleep(0.5)
    done = done or finished(demo, timeout=1)
    assert done["state"] == "done", done
    assert deepest is None or deepest < 2.5, "the robot drove through the wall, to y {:.2f}".format(deepest)
    assert "beyond its zones" in done["message"], done["message"]
    share = room_known(DEMO, str(demo.folder / "maps" / "walled.yaml"), BEDROOM)
    assert share < 0.9, "{:.0%} of the bedroom was mapped through its walled-off door".format(share)  # 77 % seen
    zones = demo.get("/zones").json()["zones"]  # now on the saved map
    assert [(z["name"], z["kind"], z["enabled"]) for z in zones] == [("Schlafzimmertür", "wall", True)]


def room_known(world_yaml, saved_yaml, room):
    """The share of the world's free floor in ``room`` (x0, y0, x1, y1) that the saved map knows as free."""
    truth, saved = mapfile.load(world_yaml), mapfile.load(saved_yaml)
    cols, rows = np.meshgrid(np.arange(truth.width), np.arange(truth.height))
    xs = truth.origin_x + (cols + 0.5) * truth.resolution
    ys = truth.origin_y + (rows + 0.5) * truth.resolution
    floor = (frontiers.as_array(truth) == 0) & (xs > room[0]) & (xs < room[2]) & (ys > room[1]) & (ys < room[3])
    scols = np.floor((xs[floor] - saved.origin_x) / saved.resolution).astype(int)
    srows = np.floor((ys[floor] - saved.origin_y) / saved.resolution).astype(int)
    inside = (scols >= 0) & (scols < saved.width) & (srows >= 0) & (srows < saved.height)
    known = frontiers.as_array(saved)[srows[inside], scols[inside]]
    return np.count_nonzero((known >= 0) & (known < 50)) / float(np.count_nonzero(floor))


def assert_stands(sim, seconds=1.0):
    """The robot comes to rest within a second and then does not move."""
    time.sleep(0.5)
    a = true_pose(sim)
    time.sleep(seconds)
    b = true_pose(sim)
    assert math.hypot(b["x"] - a["x"], b["y"] - a["y"]) < 0.01 and abs(b["yaw"] - a["yaw"]) < 0.02, (a, b)
