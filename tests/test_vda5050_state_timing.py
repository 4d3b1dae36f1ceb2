"""When the robot sends its VDA 5050 state (section 6.10): on each change that counts, and at least
every 30 s when nothing changes; a draining battery alone sends none (it rides along with the next).

The vehicle's own rule, run with a clock of the test's; the robot's parts it reads are small stand-ins
(the real ones are driven in tests/test_vda5050.py, where a 30 s wait per case would cost minutes).
"""

import json
from types import SimpleNamespace

from flask_move_server.config import Vda5050Config
from flask_move_server.vda5050.vehicle import STATE_EVERY, Vehicle


class Link:
    def __init__(self):
        self.sent = []

    def set_will(self, topic, payload):
        pass

    def say_on_close(self, topic, payload):
        pass

    def handle(self, topic, callback, **limits):
        pass

    def when_connected(self, callback):
        pass

    def publish(self, topic, payload, retain=False, qos=1):
        self.sent.append((topic.rsplit("/", 1)[1], json.loads(payload)))
        return True

    def states(self):
        return [body for kind, body in self.sent if kind == "state"]


class Robot:
    def __init__(self):
        self.latched, self.battery = False, 80.0
        self.node = SimpleNamespace(connected=False)
        self.teleop_control = SimpleNamespace(status=lambda: {"active": False})
        self.pose = SimpleNamespace(current=lambda: None)
        self.estop = SimpleNamespace(when_engaged=lambda callback: None)

    def navigation_status(self):
        return {"state": "idle"}

    def estop_status(self):
        return {"latched": self.latched, "source": "api" if self.latched else None}

    def stuck_status(self):
        return None

    def battery_status(self):
        return {"percentage": self.battery, "voltage": None, "charging": False}


def vehicle_with_clock():
    now = [1000.0]
    link, robot = Link(), Robot()
    vehicle = Vehicle(link, Vda5050Config(enabled=True), "robot", robot, runs=None, store=None, modes=None,
                      factsheet={}, clock=lambda: now[0])
    return vehicle, link, robot, now


def test_nothing_changing_sends_the_state_again_after_30_s_not_before():
    vehicle, link, _robot, now = vehicle_with_clock()
    vehicle._tell()
    assert len(link.states()) == 1
    now[0] += STATE_EVERY - 0.5
    vehicle._tell()
    assert len(link.states()) == 1
    now[0] += 0.5
    vehicle._tell()
    assert len(link.states()) == 2
    assert [s["headerId"] for s in link.states()] == [0, 1]


def test_a_draining_battery_rides_along_and_an_e_stop_is_sent_at_once():
    vehicle, link, robot, now = vehicle_with_clock()
    vehicle._tell()
    robot.battery = 79.0
    now[0] += 1
    vehicle._tell()
    assert len(link.states()) == 1
    robot.latched = True
    now[0] += 0.25
    vehicle._tell()
    assert len(link.states()) == 2
    state = link.states()[-1]
    assert state["safetyState"]["eStop"] == "REMOTE" and state["batteryState"]["batteryCharge"] == 79.0
