"""Where the robot is, and where it is believed to be, after a map switch: ``flask-move-server --sim``.

After a switch the server sets the robot's pose to the map's dock wherever the robot stands. The
simulated world keeps the robot where it really is (``/status`` ``sim.true_pose``): only what
localization believes changes, as with AMCL. The server says the pose is assumed until the owner
confirms or sets it. One real server process for the module, its own master, real ROS.
"""

import math
import shutil

import pytest

from tests.conftest import ROOT, stop_process, wait_for
from tests.test_sim_e2e import DEMO_WAYPOINTS, SimServer, _still

NOT_ASSUMED = {"assumed": False, "from": None, "since": None}
KITCHEN = (8.4, 0.9)


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    folder = tmp_path_factory.mktemp("whereabouts")
    maps = folder / "maps"
    maps.mkdir()
    for ext in ("yaml", "pgm"):
        shutil.copy("{}/config/maps/demo.{}".format(ROOT, ext), str(maps / "demo.{}".format(ext)))
    shutil.copy(DEMO_WAYPOINTS, str(maps / "demo.waypoints.yaml"))  # its dock at the origin
    server = SimServer(folder)
    yield server
    stop_process(server.proc)


def _near(pose, x, y, tolerance=0.2):
    return math.hypot(pose["x"] - x, pose["y"] - y) <= tolerance


def _truth(sim):
    return sim.status()["sim"]["true_pose"]


def _go(sim, **goal):
    r = sim.post("/goto", dict(goal, wait=120), timeout=150)
    assert r.status_code == 200 and r.json()["navigation"]["state"] == "succeeded", r.text
    wait_for(lambda: sim.status()["navigation"]["state"] == "succeeded", message="the goal's end in /status")


def test_the_sim_shows_where_the_robot_really_is(sim):
    assert _near(_truth(sim), 0.0, 0.0, 0.01) and _near(sim.pose(), 0.0, 0.0, 0.01)
    assert sim.get("/mode").json()["localization"] == NOT_ASSUMED  # the demo's own map: nothing set


def test_a_switch_sets_the_belief_to_the_dock_and_leaves_the_robot_in_the_kitchen(sim):
    _go(sim, name="kitchen")
    assert _near(_truth(sim), *KITCHEN)
    r = sim.post("/mode", {"mode": "navigation", "map": "demo", "wait": 60}, timeout=90)
    assert r.status_code == 200, r.text
    localization = r.json()["localization"]
    assert localization["assumed"] is True and localization["from"] == "dock" and localization["since"]
    wait_for(lambda: _near(sim.pose(), 0.0, 0.0, 0.05), message="the reported pose at the dock")
    assert _near(_truth(sim), *KITCHEN)  # the robot did not move: only the belief did
    assert sim.status()["mode"]["localization"]["assumed"] is True


def test_a_goal_is_driven_from_the_believed_pose(sim):
    _go(sim, x=0.5, y=0.0, yaw=0.0)  # half a metre ahead of the dock, as the robot believes
    assert _near(sim.pose(), 0.5, 0.0)
    truth = _truth(sim)  # it drove its half metre from where it really stood, in the kitchen
    assert _near(truth, KITCHEN[0] + 0.5, KITCHEN[1]), truth


def test_confirming_ends_the_assumption_and_moves_nothing(sim):
    # at rest first: a goal that just arrived may still be settling (CI saw 1.8 cm at load 4)
    wait_for(lambda: _still(sim, 0.3), timeout=30, message="the robot at rest")
    before = sim.pose()
    r = sim.post("/pose", {"confirm": True})
    assert r.status_code == 200 and r.json()["localization"] == NOT_ASSUMED, r.text
    assert sim.get("/mode").json()["localization"] == NOT_ASSUMED
    assert _near(sim.pose(), before["x"], before["y"], 0.01)


def test_setting_the_pose_to_the_truth_puts_the_belief_back(sim):
    sim.post("/mode", {"mode": "navigation", "map": "demo", "wait": 60}, timeout=90)
    assert sim.get("/mode").json()["localization"]["assumed"] is True
    truth = _truth(sim)
    r = sim.post("/pose", truth)
    assert r.status_code == 200 and r.json()["localization"] == NOT_ASSUMED, r.text
    wait_for(lambda: _near(sim.pose(), truth["x"], truth["y"], 0.02), message="the belief at the truth")
    _go(sim, name="kitchen")
    assert _near(_truth(sim), *KITCHEN)  # now it really goes there
