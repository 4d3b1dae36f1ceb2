"""The robot's modes end to end, as a user meets them: a real server process running real roslaunch.

``flask-move-server`` runs with ``modes.stack: roslaunch`` (not ``--sim``) on a ROS master of this
module, the stub packages (tests/stub_packages) standing in for gmapping, map_server, amcl,
move_base and the lidar. Everything is asked over HTTP; which stack runs is read from /proc,
independently of the server's own bookkeeping: every process (but the server and the master)
whose environment points at this module's master is part of a stack, named by its
``__name:=`` (roslaunch itself as ``roslaunch``).
"""

import os
import signal

import pytest

from flask_move_server.maps import mapfile
from tests.conftest import ServerProcess, default_sigint, free_port, start_master, stop_process, wait_for
from tests.test_launch import ros_env
from tests.test_stack_launched import stack_processes

LIDAR = {"roslaunch", "rplidar", "base_link_to_laser"}  # launch/include/lidar.launch, in every mode
MAPPING = LIDAR | {"slam_gmapping", "move_base"}  # move_base on the growing map (launch/include/move_base.launch)
NAVIGATION = LIDAR | {"map_server", "amcl", "move_base"}
GMAPPING_SIZE = (20, 10)  # the stub gmapping's map (tests/stub_packages/gmapping/slam_gmapping)
SWITCH_WAIT = 45


@pytest.fixture(scope="module")
def robot_master(tmp_path_factory):
    """A ROS master of this module's own, so its stacks are told apart from any other test's processes."""
    port = free_port()
    env = {k: v for k, v in os.environ.items() if not k.startswith("ROS_MASTER")}
    env["ROS_HOME"] = str(tmp_path_factory.mktemp("master_home"))
    proc = start_master(port, env=env)
    yield "http://127.0.0.1:{}".format(port), proc.pid
    stop_process(proc)


@pytest.fixture
def robot(robot_master, tmp_path):
    """``start(**modes)``: a server on the robot's stack; every server started is killed at the end."""
    master_uri, master_pid = robot_master
    servers = []

    def start(**modes):
        servers.append(start_server(tmp_path, master_uri, **modes))
        return servers[-1]

    start.tmp_path, start.master_uri = tmp_path, master_uri
    start.stack = lambda: running_stack(master_uri, master_pid, servers)
    yield start
    for server in servers:
        server.kill()
    assert wait_for(lambda: not start.stack(), timeout=20, message="every stack to be gone")


def start_server(tmp_path, master_uri, **modes):
    settings = dict(stack="roslaunch", start_timeout=40.0, stop_timeout=5.0, restarts=0)
    settings.update(modes)
    config = tmp_path / "robot.yaml"
    config.write_text("maps:\n  image_margin: 0.0\nmodes:\n" +
                      "".join("  {}: {}\n".format(k, v) for k, v in settings.items()))
    env = ros_env(tmp_path)
    env.update(ROS_MASTER_URI=master_uri, ROS_IP="127.0.0.1")
    return ServerProcess("--config", str(config), "--host", "127.0.0.1", "--port", "0", "--no-mdns",
                         "--motor-backend", "none", "--waypoints", str(tmp_path / "waypoints.yaml"), env=env)


def running_stack(master_uri, master_pid, servers):
    """{node name: pid} of every stack process on ``master_uri`` (not the master, not a server)."""
    ours = {master_pid} | {s.proc.pid for s in servers}
    return {node_name(cmd): pid for pid, cmd in stack_processes(master_uri).items() if pid not in ours}


def node_name(cmdline):
    """A node's ``__name:=``, ``roslaunch``, or the command line itself (a process being forked has none yet)."""
    words = cmdline.split()
    if any(os.path.basename(word) == "roslaunch" for word in words[:2]):
        return "roslaunch"
    names = [word[len("__name:="):] for word in words if word.startswith("__name:=")]
    return names[0] if names else cmdline


def switch(server, body):
    settled(server)  # the mode restored at start-up (idle without mode.json) is a switch too: 409 meanwhile
    r = server.post("/mode", dict(body, wait=SWITCH_WAIT), timeout=SWITCH_WAIT + 10)
    assert r.status_code == 200, r.text
    assert r.json()["state"] == "running", r.json()
    return r.json()


def settled(server, timeout=SWITCH_WAIT):
    """The mode once no switch is under way (running or failed)."""
    return wait_mode(server, lambda m: m["state"] in ("running", "failed"), timeout=timeout,
                     message="the switch under way to end")


def map_size(server):
    """The size of the map GET /map serves, or None while none has reached the server yet."""
    body = server.get("/map").json()
    return (body["width"], body["height"]) if "width" in body else None


def wait_mode(server, predicate, timeout=30, message="the mode"):
    return wait_for(lambda: predicate(server.get("/mode").json()), timeout=timeout, interval=0.1,
                    message=message) and server.get("/mode").json()


@pytest.mark.timeout(120)
def test_map_the_flat_save_it_navigate_on_it_switch_maps_and_stop(robot):
    server = robot()
    assert settled(server)["mode"] == "idle"  # no mode.json: idle
    assert robot.stack() == {}

    mapping = switch(server, {"mode": "mapping"})
    assert "move_base" not in mapping["message"], mapping  # running once goals reach mapping's move_base
    assert set(robot.stack()) == MAPPING
    assert server.get("/health").json()["move_base"] == "ready"  # /goto while mapping, and exploring
    wait_for(lambda: server.get("/map").status_code == 200, timeout=10, message="GET /map to serve the map")
    assert map_size(server) == GMAPPING_SIZE
    mapped = server.get("/map").json()["version"]
    image = server.get("/map/image")
    assert image.status_code == 200 and image.headers["Content-Type"] == "image/png"

    r = server.post("/maps", {"name": "flat", "then": "navigation"}, timeout=20)
    assert r.status_code == 201, r.text
    maps = robot.tmp_path / "maps"
    grid = mapfile.load(str(maps / "flat.yaml"))
    assert (grid.width, grid.height) == GMAPPING_SIZE
    assert (maps / "flat.pgm").read_bytes().startswith(b"P5\n")  # map_saver's binary greymap
    assert (maps / "flat.yaml").read_text().startswith(  # map_saver's YAML, as map_server reads it
        "image: flat.pgm\nresolution: 0.050000\norigin: [-0.500000, -0.250000, 0.000000]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    mode = wait_mode(server, lambda m: m["state"] in ("running", "failed") and m["mode"] == "navigation",
                     timeout=SWITCH_WAIT, message="navigation on the saved map")
    assert (mode["mode"], mode["map"], mode["state"]) == ("navigation", "flat", "running"), mode
    assert set(robot.stack()) == NAVIGATION
    wait_for(lambda: server.get("/map").json().get("version") not in (None, mapped), timeout=10,
             message="map_server's /map")
    assert map_size(server) == GMAPPING_SIZE  # now the stub map_server's, read from flat.yaml
    r = server.post("/pose", {"x": 0.2, "y": 0.1, "yaw": 0.5})
    assert r.status_code == 200, r.text

    mapfile.save(str(maps), "garage", mapfile.Grid(43, 11, 0.05, -1.0, -0.25, bytes(43 * 11)))
    before = set(robot.stack().values())
    switch(server, {"mode": "navigation", "map": "garage"})
    now = robot.stack()
    assert set(now) == NAVIGATION and not before & set(now.values())
    wait_for(lambda: map_size(server) == (43, 11), timeout=10, message="GET /map to show the garage")

    switch(server, {"mode": "idle"})
    assert robot.stack() == {}
    assert server.stop() == 0


def kill_node(robot, name):
    pid = robot.stack()[name]
    os.kill(pid, signal.SIGKILL)
    return pid


@pytest.mark.timeout(90)
def test_a_killed_stack_node_is_restarted_then_reported_failed(robot):
    server = robot(restarts=1)
    switch(server, {"mode": "mapping"})
    killed = "the navigation stack's slam_gmapping node was killed (signal 9)"

    kill_node(robot, "slam_gmapping")
    restarting = wait_mode(server, lambda m: m["message"].startswith("restarting"), message="the restart")
    assert (restarting["mode"], restarting["state"]) == ("mapping", "starting")
    assert restarting["message"].startswith("restarting (1 of 1) after: " + killed), restarting
    wait_mode(server, lambda m: m["state"] == "running", message="the restarted stack")
    assert set(robot.stack()) == MAPPING

    kill_node(robot, "slam_gmapping")
    failed = wait_mode(server, lambda m: m["state"] == "failed", message="the mode to fail")
    assert failed["mode"] == "mapping" and failed["message"].startswith("failed after 1 restart: " + killed), failed
    assert server.get("/status").json()["mode"] == server.get("/mode").json()
    assert wait_for(lambda: not robot.stack(), timeout=15, message="the rest of the failed stack to stop")
    assert server.get("/mode").json()["state"] == "failed"
    assert server.stop() == 0


@pytest.mark.timeout(90)
def test_a_killed_server_leaves_no_stack_and_the_next_one_comes_back_mapping(robot):
    import subprocess

    from flask_move_server.process import children

    first = robot()
    switch(first, {"mode": "mapping"})
    first.proc.kill()
    first.proc.wait()
    assert wait_for(lambda: not robot.stack(), timeout=10, message="the stack to die with its server")

    # A leftover PDEATHSIG could not reach (a node that was forking): carries the dead server's marker.
    leftover = subprocess.Popen(["sleep", "600"], env=dict(
        os.environ, ROS_MASTER_URI=robot.master_uri, **{
            children.MARKER: children.marker_value(first.proc.pid, 1)}),
        preexec_fn=default_sigint)  # SIGINT ends it, even when this pytest ignores SIGINT
    try:
        second = robot()
        mode = settled(second)
        assert (mode["mode"], mode["state"]) == ("mapping", "running"), mode
        assert leftover.wait(10) == -signal.SIGINT
        assert set(robot.stack()) == MAPPING
        assert second.stop() == 0
    finally:
        if leftover.poll() is None:
            leftover.kill()
            leftover.wait()


@pytest.mark.timeout(60)
def test_sigterm_while_navigating_stops_the_stack_and_exits_0(robot):
    maps = robot.tmp_path / "maps"
    maps.mkdir()
    mapfile.save(str(maps), "flat", mapfile.Grid(31, 21, 0.05, -0.5, -0.5, bytes(31 * 21)))
    (robot.tmp_path / "mode.json").write_text('{"mode": "navigation", "map": "flat"}\n')
    server = robot()
    mode = settled(server)
    assert (mode["mode"], mode["map"], mode["state"]) == ("navigation", "flat", "running"), mode
    assert set(robot.stack()) == NAVIGATION
    wait_for(lambda: map_size(server) == (31, 21), timeout=10, message="GET /map to serve the remembered map")
    assert server.stop(timeout=30) == 0
    assert robot.stack() == {}
