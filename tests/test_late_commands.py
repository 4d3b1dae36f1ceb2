"""Motion commands that reach the robot late are refused, not driven (``valid_until``, docs/api.md).

Against the real robot (rospy, actionlib, the scripted move_base) on the server the product runs.
A stalled Wi-Fi is played by a client that sends the request's head at once and its body only
later, as a link that stops delivering and then delivers everything it held: the robot reads the
command late by its own clock, and nothing moves.
"""

import json
import socket
import time

import pytest
import requests

from tests.conftest import hardened, wait_for
from tests.robot_fixtures import Recorder
from tests.standins.move_base import HOLD_X


def _clock(url):
    return requests.get(url + "/status", timeout=5).json()["clock"]


def _send_late(url, path, body, stall):
    """POST ``body`` with its last bytes held back ``stall`` seconds; the answer (status, JSON)."""
    host, port = url.rsplit("/", 1)[-1].split(":")
    raw = json.dumps(body).encode()
    head = ("POST {} HTTP/1.1\r\nHost: {}:{}\r\nContent-Type: application/json\r\nContent-Length: {}\r\n"
            "Connection: close\r\n\r\n").format(path, host, port, len(raw)).encode()
    with socket.create_connection((host, int(port)), timeout=10) as s:
        s.sendall(head + raw[:-3])
        time.sleep(stall)
        s.sendall(raw[-3:])
        answer = b""
        while True:
            chunk = s.recv(65536)
            if not chunk:
                break
            answer += chunk
    status = int(answer.split(b" ", 2)[1])
    return status, json.loads(answer.split(b"\r\n\r\n", 1)[1])


@pytest.fixture
def served(app, ready_robot, robot_config):
    with hardened(app, robot_config.server) as (_, url):
        yield url


def test_the_robot_tells_its_clock(served):
    first = _clock(served)
    assert abs(first - time.monotonic()) < 1.0, "the robot's monotonic clock, not the time of day"
    time.sleep(0.05)
    assert _clock(served) > first


def test_a_goal_delivered_after_its_deadline_is_refused_and_move_base_never_hears_of_it(served, move_base):
    deadline = _clock(served) + 0.5
    status, body = _send_late(served, "/goto", {"x": HOLD_X, "y": 0.0, "valid_until": deadline}, stall=1.2)
    assert status == 409 and body["error"] == "command_late"
    assert "did not act on it" in body["message"]
    time.sleep(0.3)  # a goal, had one been sent, has reached move_base by now
    assert move_base.goals == []
    assert requests.get(served + "/status", timeout=5).json()["navigation"]["state"] == "idle"


def test_the_same_goal_delivered_in_time_is_driven(served, move_base):
    deadline = _clock(served) + 3.0
    status, body = _send_late(served, "/goto", {"x": HOLD_X, "y": 0.0, "valid_until": deadline}, stall=0.2)
    assert status == 202, body
    wait_for(lambda: move_base.goals, message="the goal at move_base")
    requests.post(served + "/stop", timeout=5)


def test_a_late_joystick_command_moves_nothing(served, ready_robot, robot_config):
    from geometry_msgs.msg import Twist

    heard = Recorder(robot_config.teleop.topic, Twist)
    try:
        wait_for(lambda: ready_robot.teleop_control._pub.get_num_connections(), message="cmd_vel to connect")
        deadline = _clock(served) + 0.3
        status, body = _send_late(served, "/teleop", {"linear": 0.3, "valid_until": deadline}, stall=0.8)
        assert status == 409 and body["error"] == "command_late"
        time.sleep(0.3)
        assert heard.snapshot() == [], "not a single Twist from a late joystick command"
        assert requests.get(served + "/status", timeout=5).json()["teleop"]["active"] is False
    finally:
        heard.close()


def test_a_deadline_on_another_clock_is_refused_as_a_mistake(served, move_base):
    """A time of day (or milliseconds) would never expire: it protects nothing, so it is a 400."""
    r = requests.post(served + "/goto", json={"x": HOLD_X, "y": 0.0, "valid_until": time.time()}, timeout=5)
    assert r.status_code == 400 and "robot's clock" in r.json()["message"]
    r = requests.post(served + "/teleop", json={"linear": 0.1, "valid_until": "soon"}, timeout=5)
    assert r.status_code == 400 and "valid_until" in r.json()["message"]
    assert move_base.goals == []
