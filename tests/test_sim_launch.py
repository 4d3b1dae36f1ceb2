"""``roslaunch flask_move_server sim.launch``, and ``--sim`` refusing what it cannot simulate.

The checkout is the ROS package (package.xml at its root), put on
ROS_PACKAGE_PATH. roslaunch starts the master on a free port, the node
(scripts/flask_move_server_node) runs the server in sim mode; SIGTERM to
roslaunch must leave no process behind, the master included.
"""

import os
import shutil
import signal
import subprocess

import pytest
import requests

from tests.conftest import ROOT, free_port, run_cli, stop_process, wait_for


def _processes_mentioning(text):
    """pids of live processes whose command line contains ``text``."""
    found = []
    for pid in os.listdir("/proc"):
        if not pid.isdigit() or int(pid) == os.getpid():
            continue
        try:
            with open("/proc/{}/cmdline".format(pid), "rb") as f:
                cmdline = f.read().replace(b"\0", b" ")
            with open("/proc/{}/stat".format(pid)) as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if text.encode() in cmdline and state != "Z":
            found.append(int(pid))
    return found


def test_sim_launch_serves_the_simulated_robot_and_sigterm_ends_everything(tmp_path):
    master_port, http_port = free_port(), free_port()
    waypoints = tmp_path / "waypoints.yaml"
    shutil.copy(os.path.join(ROOT, "config", "waypoints.demo.yaml"), str(waypoints))
    env = dict(os.environ, ROS_PACKAGE_PATH=ROOT, ROS_HOME=str(tmp_path), ROS_LOG_DIR=str(tmp_path / "log"),
               ROS_MASTER_URI="http://127.0.0.1:{}".format(master_port), ROS_IP="127.0.0.1")
    proc = subprocess.Popen(
        [shutil.which("roslaunch") or "roslaunch", "-p", str(master_port), "flask_move_server", "sim.launch",
         "port:={}".format(http_port), "waypoints:={}".format(waypoints), "output:=log"],
        env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    url = "http://127.0.0.1:{}".format(http_port)
    try:
        health = wait_for(lambda: _health(url), timeout=60, message="sim.launch to answer /health")
        assert health == {"status": "ok", "ros": "connected", "move_base": "ready"}
        status = requests.get(url + "/status", timeout=10).json()
        assert status["motors"]["backend"] == "sim"
        assert {w["name"] for w in requests.get(url + "/waypoints", timeout=10).json()["waypoints"]} >= {
            "kitchen", "office", "dock"}
        launched = _processes_mentioning("--port {}".format(http_port))
        masters = _processes_mentioning("-p {}".format(master_port))
        assert launched and masters
        proc.send_signal(signal.SIGTERM)
        proc.wait(30)
        wait_for(lambda: not _processes_mentioning("--port {}".format(http_port)), timeout=15,
                 message="the server node to exit")
        assert not _processes_mentioning("-p {}".format(master_port)), "the ROS master was left running"
    finally:
        stop_process(proc)


def _health(url):
    try:
        body = requests.get(url + "/health", timeout=2).json()
    except (requests.RequestException, ValueError):
        return None
    return body if body.get("move_base") == "ready" else None


@pytest.mark.parametrize("args, expected", [
    (["--map", "no-such-map.yaml"], "no-such-map.yaml: cannot read the map"),
    (["--motor-backend", "none"], "drive.backend: --sim needs the sim motor backend"),
])
def test_sim_refuses_what_it_cannot_simulate_and_leaves_no_master(tmp_path, args, expected):
    master_port = free_port()
    env = {"ROS_MASTER_URI": "http://127.0.0.1:{}".format(master_port), "ROS_HOME": str(tmp_path)}
    proc = run_cli("--sim", "--port", "0", "--no-mdns", "--waypoints", str(tmp_path / "w.yaml"), *args,
                   env=env, cwd=str(tmp_path))
    try:
        _, err = proc.communicate(timeout=60)
    finally:
        stop_process(proc)
    assert proc.returncode == 2 and expected in err, err
    assert not _processes_mentioning("-p {}".format(master_port))
