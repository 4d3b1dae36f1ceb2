"""The shipped launch files against the simulated world: ``--sim`` with ``modes.stack: roslaunch``.

On a PC with ROS Noetic's navigation packages this runs the real gmapping, AMCL and move_base on
the simulated flat. Here those packages do not exist, so roslaunch starts the stub packages in
their place (tests/stub_packages): each listens as the real node does and reports what it would
have had to work with (``~inputs``). The world must give them all of it: /scan in the laser's
frame at the lidar's rate with one beam count, tf odom -> base_link -> laser at each scan's
stamp, and the base's velocity on /odom; and the sim's own stand-ins must be gone.
"""

import os
import shutil
import xmlrpc.client

import pytest

from tests.conftest import ROOT, ServerProcess, SimReads, free_port, stop_process, wait_for
from tests.test_launch import ros_env

DEMO_WAYPOINTS = os.path.join(ROOT, "config", "waypoints.demo.yaml")


class RealStackSim(SimReads, ServerProcess):
    def __init__(self, folder):
        self.master_uri = "http://127.0.0.1:{}".format(free_port())
        waypoints = folder / "waypoints.yaml"
        shutil.copy(DEMO_WAYPOINTS, str(waypoints))
        config = folder / "sim.yaml"
        config.write_text("modes:\n  stack: roslaunch\n")
        env = ros_env(folder)
        env.update(ROS_MASTER_URI=self.master_uri, ROS_IP="127.0.0.1")
        super().__init__("--sim", "--config", str(config), "--host", "127.0.0.1", "--port", "0", "--no-mdns",
                         "--waypoints", str(waypoints), env=env, start_timeout=60)

    def param(self, name):
        return xmlrpc.client.ServerProxy(self.master_uri).getParam("/test", name)[2]

    def publishers(self, topic):
        _, _, (pubs, _, _) = xmlrpc.client.ServerProxy(self.master_uri).getSystemState("/test")
        return next((nodes for name, nodes in pubs if name == topic), [])

    def switch(self, body):
        r = self.post("/mode", dict(body, wait=70), timeout=80)
        assert r.status_code == 200 and r.json()["state"] == "running", r.text


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = RealStackSim(tmp_path_factory.mktemp("real_stack"))
    wait_for(lambda: server.publishers("/scan"), timeout=30, message="the world's /scan")
    yield server
    stop_process(server.proc)


def wait_inputs(sim, node):
    wait_for(lambda: isinstance(sim.param("/{}/inputs".format(node)), dict), timeout=30,
             message="{}'s report of its inputs".format(node))
    return sim.param("/{}/inputs".format(node))


def assert_fed(inputs, odom=False):
    assert inputs["scans"] > 5 and 4.0 <= inputs["scan_rate"] <= 10.0, inputs
    assert inputs["scan_frame"] == "laser" and inputs["beams"] == [360] and inputs["range_max"] > 0, inputs
    assert all(ok is True for ok in inputs["links"].values()), inputs["links"]
    assert set(inputs["links"]) == {"odom -> base_link", "base_link -> @scan"}
    if odom:
        assert inputs["odom_rate"] >= 10.0, inputs


def test_idle_is_the_world_alone(sim):
    assert sim.get("/mode").json()["mode"] == "idle"
    assert sim.publishers("/scan") and sim.publishers("/odom")
    assert sim.publishers("/amcl_pose") == []   # no AMCL stand-in
    assert sim.get("/health").json()["move_base"] == "unavailable"  # no move_base stand-in


def test_gmapping_and_move_base_get_what_they_need_from_the_world(sim):
    sim.switch({"mode": "mapping"})
    assert_fed(wait_inputs(sim, "slam_gmapping"))
    assert_fed(wait_inputs(sim, "move_base"), odom=True)  # mapping runs move_base on the growing map
    assert sim.publishers("/scan") == ["/flask_move_server"]  # the world's lidar, not rplidar (lidar:=false)
    assert sim.get("/health").json()["move_base"] == "ready"  # the stack's move_base, not a stand-in
    xmlrpc.client.ServerProxy(sim.master_uri).deleteParam("/test", "/move_base/inputs")  # navigation's own next


def test_amcl_and_move_base_get_what_they_need_on_the_sim_s_own_map(sim):
    sim.switch({"mode": "navigation"})
    assert_fed(wait_inputs(sim, "amcl"))
    assert_fed(wait_inputs(sim, "move_base"), odom=True)
    assert sim.publishers("/amcl_pose") == []
    assert "/map_server" in sim.publishers("/map")
    assert sim.get("/health").json()["move_base"] == "ready"  # the stack's move_base, not a stand-in
