"""The simulated move_base drives by the robot's own DWA configuration, and fails where the robot would.

A real ``flask-move-server --sim``: with the shipped config/ the robot drives off from
standstill; with the files as shipped before issue 19 (tests/data/unfit_nav_config/), on
which the real dwa_local_planner finds no valid velocity from rest, the goal is aborted with
that reason and the robot never moves, as on the robot.
"""

import math
import os

import pytest

from flask_move_server import config as config_mod
from flask_move_server.core.errors import ConfigError
from flask_move_server.sim import dwa
from flask_move_server.sim.runner import planner_limits
from tests.conftest import ROOT, stop_process
from tests.test_sim_e2e import SimServer

UNFIT = os.path.join(ROOT, "tests", "data", "unfit_nav_config")


@pytest.fixture(scope="module")
def unfit_sim(tmp_path_factory):
    server = SimServer(tmp_path_factory.mktemp("unfit"), "  navigation_config: {}\n".format(UNFIT))
    yield server
    stop_process(server.proc)


def test_a_configuration_dwa_cannot_start_with_does_not_drive_the_sim_and_says_why(unfit_sim):
    before = unfit_sim.pose()
    r = unfit_sim.post("/goto", {"name": "kitchen", "wait": 30}, timeout=40)
    assert r.status_code == 409 and r.json()["error"] == "navigation_failed", r.text
    message = r.json()["message"]
    assert "no valid trajectory" in message and "min_vel_theta 0.9" in message, message
    after = unfit_sim.pose()
    assert math.hypot(after["x"] - before["x"], after["y"] - before["y"]) < 0.01
    assert abs(after["yaw"] - before["yaw"]) < 0.01
    assert unfit_sim.find(r"cannot start from standstill")


def test_the_sim_drives_with_the_shipped_limits(tmp_path):
    config = config_mod.load(os.path.join(ROOT, "config", "robot.yaml"))
    limits = planner_limits(config.sim)
    assert limits == dwa.load(os.path.join(ROOT, "config"))
    assert limits.move_base_frequency == 4.0 and limits.max_vel_x == 0.3


def test_a_missing_navigation_config_is_a_config_error_naming_it(tmp_path):
    config = config_mod.build(config_mod.Config, {"sim": {"navigation_config": str(tmp_path)}})
    with pytest.raises(ConfigError) as err:
        planner_limits(config.sim)
    assert "move_base.yaml" in str(err.value) and "sim.navigation_config" in str(err.value)


def test_a_sim_key_that_moved_says_where_it_went(tmp_path):
    with pytest.raises(ConfigError) as err:
        config_mod.build(config_mod.Config, {"sim": {"max_linear": 0.5}})
    assert "sim.max_linear" in str(err.value) and "max_vel_x" in str(err.value)


def test_every_velocity_the_stand_in_sends_is_one_dwa_may_choose():
    limits = dwa.load(os.path.join(ROOT, "config"))
    for current in [(0.0, 0.0), (0.1, 0.0), (0.3, 1.2), (0.0, -1.0), (0.2, 0.5)]:
        for wanted in [(0.3, 0.0), (0.0, 0.9), (0.05, -0.2), (-0.1, 0.0)]:
            chosen = dwa.nearest(limits, wanted, current)
            assert chosen in dwa.samples(limits, *current)
            (x_low, x_high), (th_low, th_high) = dwa.window(limits, *current)
            assert x_low <= chosen[0] <= x_high and th_low <= chosen[1] <= th_high
