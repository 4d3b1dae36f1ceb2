"""The server as a user runs it: a real process, a real master that comes and goes, signals."""

import os
import signal
import subprocess
import sys
import time

import pytest
import requests

from tests.conftest import ServerProcess, default_sigint, free_port, start_master, stop_process, wait_for


def start_server(tmp_path, master_port, *extra):
    """The server with its own waypoints, pointed at the master on ``master_port`` (running or not)."""
    env = {"ROS_MASTER_URI": "http://127.0.0.1:{}".format(master_port), "ROS_HOME": str(tmp_path),
           "ROS_IP": "127.0.0.1"}
    server = ServerProcess("--host", "127.0.0.1", "--port", "0", "--no-mdns",
                           "--waypoints", str(tmp_path / "waypoints.yaml"), *extra, env=env)
    server.master_uri = env["ROS_MASTER_URI"]
    return server


@pytest.fixture
def master_port():
    return free_port()


@pytest.fixture
def server_factory(tmp_path):
    servers = []

    def make(master_port, *extra):
        servers.append(start_server(tmp_path, master_port, *extra))
        return servers[-1]

    yield make
    for s in servers:
        s.kill()


def test_serves_before_ros_and_connects_when_the_master_starts(server_factory, master_port):
    server = server_factory(master_port)
    assert server.get("/health").json() == {"status": "ok", "ros": "waiting", "move_base": "unavailable"}
    r = server.post("/goto", {"x": 1, "y": 2})
    assert r.status_code == 503
    assert r.json()["error"] == "ros_unavailable" and server.master_uri in r.json()["message"]
    assert server.post("/teleop", {"linear": 0.1}).status_code == 503
    assert server.post("/stop").status_code == 200
    master = start_master(master_port)
    try:
        wait_for(lambda: server.get("/health").json()["ros"] == "connected", timeout=30,
                 message="the server to connect to the master started after it")
        assert server.get("/status").json()["ros"]["node"] == "/flask_move_server"
        assert server.stop() == 0
    finally:
        stop_process(master)


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_stops_the_server_with_status_0(server_factory, master_port, sig):
    master = start_master(master_port)
    try:
        server = server_factory(master_port)
        wait_for(lambda: server.get("/health").json()["ros"] == "connected", timeout=30)
        started = time.monotonic()
        assert server.stop(sig) == 0
        assert time.monotonic() - started < 10
        assert server.find("received {}, stopping".format(sig.name))
        with pytest.raises(requests.ConnectionError):
            server.get("/health")
    finally:
        stop_process(master)


def test_a_lost_master_shows_in_health_and_a_new_one_restarts_the_server(server_factory, master_port):
    master = start_master(master_port)
    server = server_factory(master_port)
    try:
        wait_for(lambda: server.get("/health").json()["ros"] == "connected", timeout=30)
        stop_process(master)
        wait_for(lambda: server.get("/health").json()["ros"] == "lost", timeout=15,
                 message="/health to report the lost master")
        assert server.post("/goto", {"x": 1, "y": 2}).status_code == 503
        master = start_master(master_port)
        assert server.proc.wait(20) == 3, "a replaced master makes the server exit 3 for systemd"
        assert server.find("a new ROS master answers")
    finally:
        stop_process(master)


def test_roslaunch_setting_a_run_id_on_the_running_master_is_not_a_new_master(server_factory, master_port):
    """``rosmaster --core`` has no ``/run_id``; a roslaunch run against it sets one. Same master: keep serving."""
    import xmlrpc.client

    master = start_master(master_port)
    server = server_factory(master_port)
    try:
        wait_for(lambda: server.get("/health").json()["ros"] == "connected", timeout=30)
        xmlrpc.client.ServerProxy(server.master_uri).setParam("/roslaunch", "/run_id", "4d1c5a0e-roslaunch")
        time.sleep(3)  # three master checks (ros.master_check_period is 1 s)
        assert server.proc.poll() is None, "the server exited: it took the same master for a new one"
        assert server.get("/health").json()["ros"] == "connected"
        assert not server.find("a new ROS master answers")
    finally:
        stop_process(master)


@pytest.fixture
def master(master_port):
    """A real ROS master on ``master_port`` for the test, stopped after it."""
    process = start_master(master_port)
    yield process
    stop_process(process)


def connected(server):
    """``server`` once its /health says it is connected to the master."""
    wait_for(lambda: server.get("/health").json()["ros"] == "connected", timeout=30)
    return server


def test_a_second_server_on_the_same_master_refuses_and_leaves_the_first_running(server_factory, master_port, master):
    """rospy would shut the first server's node down for the second: the robot the first drives must not be stranded."""
    first = connected(server_factory(master_port))
    second = server_factory(master_port)
    assert second.proc.wait(20) == 1, "the second server did not refuse"
    assert second.find(r"another node runs as /flask_move_server .*\(pid \d+\).*systemctl stop flask-move-server")
    time.sleep(1.5)  # two master checks: the first would have been shut down by now
    assert first.proc.poll() is None and first.get("/health").json()["ros"] == "connected"


def test_a_node_that_takes_the_name_later_stops_the_server_saying_why(server_factory, master_port, master, tmp_path):
    """Any other node registering our name makes rospy shut ours down: the server must not claim 'connected'."""
    server = connected(server_factory(master_port))
    env = dict(os.environ, ROS_MASTER_URI=server.master_uri, ROS_HOME=str(tmp_path), ROS_IP="127.0.0.1")
    usurper = subprocess.Popen([sys.executable, "-c", "import rospy; rospy.init_node('flask_move_server'); "
                                "rospy.spin()"], env=env, preexec_fn=default_sigint)
    try:
        assert server.proc.wait(20) == 3, "the server kept serving without its ROS node"
        assert server.find("another node registered as /flask_move_server")
    finally:
        stop_process(usurper)


def test_a_dead_servers_leftover_registration_does_not_block_the_next(server_factory, master_port, master):
    """A server killed with SIGKILL stays registered with the master; the next one (systemd's restart) takes over."""
    first = connected(server_factory(master_port))
    first.proc.kill()
    first.proc.wait(10)
    second = connected(server_factory(master_port))
    assert second.proc.poll() is None
