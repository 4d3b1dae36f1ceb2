"""The stop path of ``flask-move-server --sim`` as a user meets it: signals, abuse, busy workers.

Real server processes (simulated robot, its own ROS master), real sockets.
Item 1 of issue 10: SIGTERM stops the robot before waitress drains, and a
waiting /goto answers a JSON 503. Item 2: 300 connections held open by a
client without a token do not lock the owner's ``POST /stop`` out, nor does a
``/goto`` with ``wait`` holding the only worker thread.
"""

import re
import shutil
import threading
import time

import pytest
import requests

from tests.conftest import ROOT, ServerProcess, free_port, stop_process, wait_for
from tests.hostile import HostileClients

TOKEN = "stop-path-test-token"
AUTH = {"Authorization": "Bearer " + TOKEN}
FAR = {"x": 8.4, "y": 0.9, "yaw": 0.0}  # the demo flat's kitchen: many seconds of driving


class DrivingSim(ServerProcess):
    """``flask-move-server --sim`` with a token and ``extra`` server settings."""

    def __init__(self, tmp_path, extra=""):
        master_port = free_port()
        waypoints = tmp_path / "waypoints.yaml"
        shutil.copy(str(ROOT) + "/config/waypoints.demo.yaml", str(waypoints))
        config = tmp_path / "sim.yaml"
        config.write_text("server:\n  token: {}\n{}".format(TOKEN, extra))
        env = {"ROS_MASTER_URI": "http://127.0.0.1:{}".format(master_port), "ROS_HOME": str(tmp_path),
               "ROS_LOG_DIR": str(tmp_path / "log"), "ROS_IP": "127.0.0.1"}
        super().__init__("--sim", "--config", str(config), "--port", "0", "--no-mdns",
                         "--waypoints", str(waypoints), env=env, start_timeout=60)
        self.port = int(self.url.rsplit(":", 1)[1])
        wait_for(lambda: self.get("/health").json().get("move_base") == "ready", timeout=30,
                 message="move_base stand-in ready")

    def call(self, method, path, body=None, timeout=10):
        return requests.request(method, self.url + path, json=body, headers=AUTH, timeout=timeout)

    def findall(self, pattern):
        return [line for line in list(self.lines) if re.search(pattern, line)]

    def motors(self):
        motors = self.call("GET", "/status").json()["motors"]
        return motors["left"], motors["right"]

    def wait_driving(self):
        wait_for(lambda: self.motors() != (0.0, 0.0), timeout=20, message="the robot to drive")


class Waiter(threading.Thread):
    """A client whose ``POST /goto`` with ``wait`` is in flight."""

    def __init__(self, server):
        super().__init__(daemon=True)
        self.server = server
        self.response = self.error = None

    def run(self):
        try:
            self.response = self.server.call("POST", "/goto", dict(FAR, wait=60), timeout=60)
        except requests.RequestException as exc:
            self.error = exc


@pytest.fixture(scope="module")
def one_worker(tmp_path_factory):
    """A sim server with one HTTP worker thread and the default connection policy."""
    server = DrivingSim(tmp_path_factory.mktemp("one_worker"), "  threads: 1\n")
    yield server
    stop_process(server.proc)


def test_sigterm_stops_the_robot_first_and_a_waiting_goto_answers_503(tmp_path):
    server = DrivingSim(tmp_path)
    try:
        waiter = Waiter(server)
        waiter.start()
        server.wait_driving()
        assert server.stop() == 0
        waiter.join(10)
        assert waiter.error is None, "the waiting client lost its connection: {!r}".format(waiter.error)
        assert waiter.response.status_code == 503
        assert waiter.response.headers["Content-Type"] == "application/json; charset=utf-8"
        assert waiter.response.json()["error"] == "shutting_down"
        stopped = server.find(r"robot stopped .* motors left (\S+) right (\S+)")
        assert stopped and float(stopped.group(1)) == 0.0 and float(stopped.group(2)) == 0.0
    finally:
        server.kill()


def test_stop_answers_and_stops_the_robot_with_300_hostile_connections_open(one_worker):
    one_worker.call("POST", "/goto", FAR)
    one_worker.wait_driving()
    with HostileClients("127.0.0.1", one_worker.port, count=300) as hostile:
        time.sleep(2)  # the slow-loris connections have begun their requests
        assert hostile.open_count() > 250
        answer = one_worker.call("POST", "/stop", timeout=5)
        assert answer.status_code == 200 and answer.json()["canceled_goal"] is True
        wait_for(lambda: one_worker.motors() == (0.0, 0.0), timeout=5, message="the motors to stop")


def test_stop_answers_while_a_waiting_goto_holds_the_only_worker(one_worker):
    one_worker.call("POST", "/goto", FAR)
    one_worker.wait_driving()
    goals = len(one_worker.findall(r"goal \d+: pose"))
    waiter = Waiter(one_worker)
    waiter.start()
    wait_for(lambda: len(one_worker.findall(r"goal \d+: pose")) > goals, message="the waiting goal to be sent")
    answer = one_worker.call("POST", "/stop", timeout=5)
    assert answer.status_code == 200 and answer.json()["canceled_goal"] is True
    waiter.join(10)
    assert waiter.response.status_code == 409 and waiter.response.json()["state"] == "canceled"
    wait_for(lambda: one_worker.motors() == (0.0, 0.0), timeout=5, message="the motors to stop")
