"""Going home before empty, in the demo flat: ``flask-move-server --sim``, real ROS, the sim's battery.

A round started a little above ``dock.return_below`` runs the battery below it on its way: the
run is paused (not canceled), the robot docks, charges to ``dock.resume_above`` and the round
goes on by itself to its end, saying so. Below ``dock.critical_below`` a goal is refused and home
is not. The thresholds are the owner's config, set close together here so the sim's battery
(1 % every 10 m, +1 % every 10 s on the charger, at 4 times real time) crosses them in a minute.
Without a battery reading nothing of this happens (``LowBattery`` over a robot that hears none).
"""

import pytest

from flask_move_server.config import DockConfig
from flask_move_server.dock.low_battery import LowBattery
from tests.conftest import stop_process, wait_for
from tests.sse import EventReader
from tests.test_sim_e2e import SimServer

LOW = "  battery_start: 0.25\ndock:\n  return_below: 0.24\n  resume_above: 0.27\n  critical_below: 0.1\n"
CRITICAL = "  battery_start: 0.08\n"


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = SimServer(tmp_path_factory.mktemp("low_battery"), sim_config=LOW)
    yield server
    stop_process(server.proc)


def _percentage(sim):
    return sim.status()["battery"]["percentage"]


def test_a_round_on_a_low_battery_goes_home_charges_and_finishes_by_itself(sim):
    wait_for(lambda: sim.status()["battery"], timeout=10, message="the sim's battery heard")
    with EventReader(sim.url, kinds=["run"], timeout=240) as runs:
        r = sim.post("/runs", {"waypoints": ["kitchen", "bedroom"]})
        assert r.status_code == 202, r.text
        run_id = r.json()["run"]["id"]
        paused = runs.until(lambda kind, run: run["state"] == "paused", timeout=120)[1]
        assert paused["id"] == run_id
        assert paused["message"].startswith("Battery 2") and "gone home to charge; the run goes on by itself at " \
            "27 %." in paused["message"], paused
        dock = wait_for(lambda: sim.status()["dock"] if sim.status()["dock"]["state"] in ("charging", "failed")
                        else None, timeout=120, message="docked on the charger")
        assert dock["state"] == "charging" and dock["message"] == "Charging at dock.", dock
        went_on = runs.until(lambda kind, run: run["state"] == "running" and run["message"], timeout=120)[1]
        assert went_on["message"].startswith("Charged to 27 % at dock: the run went on by itself."), went_on
        assert _percentage(sim) >= 27.0
        done = runs.until(lambda kind, run: run["state"] not in ("running", "paused"), timeout=120)[1]
    assert done["state"] == "succeeded", done
    assert [v["name"] for v in done["visited"]] == ["kitchen", "bedroom"]
    assert done["message"] == "Visited every waypoint (1 loop). It went home to charge on the way, once."
    assert sim.status()["dock"]["state"] == "undocked"  # it backed off the charger to go on


@pytest.fixture(scope="module")
def flat_battery(tmp_path_factory):
    server = SimServer(tmp_path_factory.mktemp("critical"), sim_config=CRITICAL)
    yield server
    stop_process(server.proc)


def test_below_critical_a_goal_is_refused_and_home_is_not(flat_battery):
    sim = flat_battery
    wait_for(lambda: sim.status()["battery"], timeout=10, message="the sim's battery heard")
    r = sim.post("/goto", {"name": "kitchen"})
    assert r.status_code == 409 and r.json()["error"] == "battery_critical", r.text
    assert r.json()["message"].startswith("The battery is at 8 %, below dock.critical_below (10 %)")
    r = sim.post("/dock", {"wait": 60}, timeout=70)  # it may have gone home by itself already: the same answer
    assert r.status_code == 200 and r.json()["dock"]["state"] == "charging", r.text


class _Robot:
    """What LowBattery reads of a robot that never heard a battery."""

    class estop:
        latched = False

    class teleop_control:
        @staticmethod
        def status():
            return {"active": False, "by": None}

    @staticmethod
    def battery_status():
        return None


class _Docking:
    def __init__(self):
        self.docked = []

    def status(self):
        return {"state": "undocked", "place": None}

    def place(self):
        return object()

    def dock(self, **kw):
        self.docked.append(kw)


def test_without_a_battery_reading_the_robot_never_goes_home_by_itself():
    docking = _Docking()
    low = LowBattery(_Robot(), docking, None, DockConfig())
    for _ in range(3):
        low.look()
    assert docking.docked == []


HOME_FIRST = "  battery_start: 0.21\ndock:\n  return_below: 0.24\n  resume_above: 0.27\n  critical_below: 0.1\n"


@pytest.fixture(scope="module")
def going_home(tmp_path_factory):
    server = SimServer(tmp_path_factory.mktemp("home_first"), sim_config=HOME_FIRST)
    yield server
    stop_process(server.proc)


def test_a_round_started_while_it_goes_home_to_charge_waits_for_the_charge_then_runs(going_home):
    """Found walking the demo as an owner: a round started at 18 % drove off while the robot docked, and the
    docking, its lane left, failed three times. Now the run begins paused, and goes on once charged."""
    sim = going_home
    wait_for(lambda: sim.status()["dock"]["state"] in ("going", "approaching", "docked", "charging"), timeout=30,
             message="the robot going home by itself below return_below")
    with EventReader(sim.url, kinds=["run"], timeout=240) as runs:
        r = sim.post("/runs", {"waypoints": ["kitchen"]})
        assert r.status_code == 202, r.text
        run = r.json()["run"]
        assert run["state"] == "paused", run
        assert run["message"].startswith("Battery 2") and run["message"].endswith(
            "the robot goes home to charge first; the run starts by itself at 27 %."), run
        dock = wait_for(lambda: sim.status()["dock"] if sim.status()["dock"]["state"] in ("charging", "failed")
                        else None, timeout=120, message="docked on the charger")
        assert dock["state"] == "charging", dock
        went_on = runs.until(lambda kind, r: r["id"] == run["id"] and r["state"] == "running", timeout=120)[1]
        assert went_on["message"].startswith("Charged to 27 % at dock: the run went on by itself."), went_on
        done = runs.until(lambda kind, r: r["state"] not in ("running", "paused"), timeout=120)[1]
    assert done["state"] == "succeeded" and [v["name"] for v in done["visited"]] == ["kitchen"], done
