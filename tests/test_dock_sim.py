"""Home onto the charger in the demo flat: ``flask-move-server --sim``, one real server for the module.

The sim's charger is as strict as a real one (``sim/battery.py`` ``on_contacts``: the robot's true
pose within 4 cm sideways and 5° of the dock, touching), so these are docking's real outcomes:
from the kitchen it ends ``charging`` and the battery rises; a goal while docked backs off the
charger first; a localization 8 cm off sideways (``tests/believer.py``) misses, and once it is put
right the next try docks; left wrong, three misses end ``failed`` in front of the charger.
"""

import math
import subprocess
import sys

import pytest

from flask_move_server.core.geometry import Pose2D
from flask_move_server.sim.battery import on_contacts
from tests.conftest import ROOT, stop_process, wait_for
from tests.sse import EventReader
from tests.test_sim_e2e import SimServer

DOCK = Pose2D(0.0, 0.0, 0.0)  # the demo's dock, facing +x; its staging pose 0.4 m behind, at x -0.4
CONFIG = "  battery_start: 0.5\n"


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = SimServer(tmp_path_factory.mktemp("dock"), sim_config=CONFIG)
    yield server
    stop_process(server.proc)


@pytest.fixture
def believer(sim):
    """Tells the sim's localization where the robot is: ``believe(x, y, yaw, sigma=0.01)``."""
    env = {"ROS_MASTER_URI": sim.master_uri, "ROS_IP": "127.0.0.1", "PYTHONPATH": ROOT}
    proc = subprocess.Popen([sys.executable, "-m", "tests.believer"], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True, env=dict(__import__("os").environ, **env), cwd=ROOT)
    assert proc.stdout.readline().strip() == "ready"

    def believe(x, y, yaw, sigma=0.01):
        proc.stdin.write("{} {} {} {}\n".format(x, y, yaw, sigma))
        proc.stdin.flush()
        assert proc.stdout.readline().strip() == "published"
    yield believe
    stop_process(proc)


def _truth(sim):
    true = sim.status()["sim"]["true_pose"]
    return Pose2D(true["x"], true["y"], true["yaw"])


def _go(sim, name):
    r = sim.post("/goto", {"name": name, "wait": 120}, timeout=130)
    assert r.status_code == 200, r.text


def _dock_events(sim):
    return EventReader(sim.url, kinds=["dock"], timeout=180)


def _until(events, state):
    """The dock events up to the first in ``state`` (that one included)."""
    said = []
    while not said or said[-1]["state"] != state:
        said.append(events.next()[1])
    return said


def test_home_from_the_kitchen_ends_charging_and_the_battery_rises(sim):
    _go(sim, "kitchen")
    assert sim.status()["dock"]["state"] == "undocked"
    with _dock_events(sim) as events:
        events.next()  # the replayed one
        r = sim.post("/dock", {"wait": 120}, timeout=130)
        assert r.status_code == 200, r.text
        said = _until(events, "charging")
    dock = r.json()["dock"]
    assert dock["state"] == "charging" and dock["place"] == "dock" and dock["tries"] == 1 and dock["confirmed"]
    assert dock["message"] == "Charging at dock."
    assert [s["state"] for s in said] == ["going", "approaching", "charging"], said
    assert on_contacts(DOCK, _truth(sim))
    start = wait_for(lambda: sim.status()["battery"] if sim.status()["battery"]["charging"] else None, timeout=10,
                     message="the battery charging")
    wait_for(lambda: sim.status()["battery"]["percentage"] >= start["percentage"] + 0.5, timeout=30,
             message="the battery rising")
    again = sim.post("/dock")
    assert again.status_code == 202 and again.json()["dock"]["state"] == "charging"  # docked already: nothing new


def test_a_goal_while_docked_backs_off_the_charger_first(sim):
    assert sim.status()["dock"]["state"] == "charging"
    with _dock_events(sim) as events:
        events.next()
        r = sim.post("/goto", {"name": "kitchen"})
        assert r.status_code == 202, r.text
        said = _until(events, "undocked")
    assert [s["state"] for s in said] == ["undocking", "undocked"], said
    backed = _truth(sim)
    assert -0.45 <= backed.x <= -0.3 and abs(backed.y) < 0.05  # straight back, to the staging pose
    wait_for(lambda: sim.status()["navigation"]["state"] == "succeeded", timeout=120, message="on to the kitchen")
    assert sim.post("/undock").json()["error"] == "dock_failed"  # not on a charger


def test_a_belief_off_sideways_misses_and_once_put_right_the_next_try_docks(sim, believer):
    true = _truth(sim)
    believer(true.x, true.y + 0.08, true.yaw)  # AMCL sure of a pose 8 cm off
    with _dock_events(sim) as events:
        events.next()
        assert sim.post("/dock").status_code == 202
        missed = _until(events, "approaching")
        while not missed[-1]["message"].startswith("Missed"):
            missed.append(events.next()[1])
        assert missed[-1]["message"].startswith("Missed the charger at dock (try 1 of 3): the battery never said")
        true = _truth(sim)
        believer(true.x, true.y, true.yaw, 0.05)  # put right: a fresh estimate, close enough to converge
        said = _until(events, "charging")
    assert said[-1]["tries"] == 2, [s["message"] for s in said]
    assert on_contacts(DOCK, _truth(sim))


def test_left_wrong_three_misses_end_failed_in_front_of_the_charger(sim, believer):
    _go(sim, "kitchen")
    true = _truth(sim)
    believer(true.x, true.y + 0.08, true.yaw)
    r = sim.post("/dock", {"wait": 170}, timeout=180)
    assert r.status_code == 409 and r.json()["error"] == "dock_failed", r.text
    dock = sim.status()["dock"]
    assert dock["state"] == "failed" and dock["tries"] == 3, dock
    assert dock["message"].startswith("Could not dock at dock: the battery never said it charges (3 tries)")
    true = _truth(sim)
    assert not on_contacts(DOCK, true) and math.hypot(true.x + 0.4, true.y + 0.08) < 0.1  # at the staging pose
    assert not sim.status()["battery"]["charging"]


def test_robotctl_docks_once_localization_is_right_and_undocks(sim, believer, capsys):
    from flask_move_server.robotctl import cli

    true = _truth(sim)
    believer(true.x, true.y, true.yaw, 0.05)  # put right where it waits, in front of the charger
    assert cli.main(["--url", sim.url, "dock", "--wait", "--timeout", "120"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == "Charging at dock."
    assert cli.main(["--url", sim.url, "status"]) == 0
    assert "dock:       Charging at dock." in capsys.readouterr().out.splitlines()
    assert cli.main(["--url", sim.url, "undock"]) == 0
    wait_for(lambda: sim.status()["dock"]["state"] == "undocked", timeout=30, message="off the charger")
    assert cli.main(["--url", sim.url, "undock"]) == 1
    assert "not on a charger" in capsys.readouterr().err
