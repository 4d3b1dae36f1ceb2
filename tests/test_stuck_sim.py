"""A robot wedged on the office door's jamb in the demo flat says so and gets itself out:
``flask-move-server --sim``, one real server process for the module, its own master, real ROS.

Driven by the joystick into the jamb, the simulated robot's wheels turn and it does not move (the
sim's body stops at the wall; its odometry, like the L298N drive's, counts the commands): the server
says it is pressed against something, stops the push, and puts its position back, which slid into
the wall with the odometry as the real robot's did (issue 33). Asked to back out, it does, slowly,
and goes on to the office. Each change is a ``stuck`` event on ``GET /events``. The wedge a goal of
its own drives it into (held, backed out, sent again) is tests/test_stuck_ros.py's, on real topics.
"""

import math
import time

import pytest

from tests.conftest import stop_process, wait_for
from tests.sse import EventReader
from tests.test_sim_e2e import SimServer

JAMB = (0.2, 1.9, 1.57)  # south of the office door's west jamb (the wall at y 2.45 ends at x 0.3), facing it
OFFICE = (-0.8, 4.3)


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = SimServer(tmp_path_factory.mktemp("stuck"))
    yield server
    stop_process(server.proc)


def _truth(sim):
    return sim.status()["sim"]["true_pose"]


def test_pressed_on_the_jamb_by_the_joystick_it_says_so_within_seconds_and_puts_its_position_back(sim):
    x, y, yaw = JAMB
    r = sim.post("/goto", {"x": x, "y": y, "yaw": yaw, "wait": 60}, timeout=70)
    assert r.status_code == 200, r.text
    pressed_at = None
    started = time.monotonic()
    while time.monotonic() - started < 15:
        stuck = sim.status()["stuck"]
        if stuck["state"] == "stuck":
            break
        if pressed_at is None and _truth(sim)["y"] > 2.25:
            pressed_at = time.monotonic()  # against the wall from here on
        sim.post("/teleop", {"linear": 0.2, "angular": 0.0})
        time.sleep(0.1)
    assert stuck["state"] == "stuck" and stuck["waiting"], stuck
    assert stuck["message"].startswith("Pressed against something near sofa: let it back out by itself, or drive")
    assert pressed_at is not None and time.monotonic() - pressed_at < 8.0  # within a few seconds
    assert not sim.status()["teleop"]["active"]  # it stopped pushing
    assert sim.status()["navigation"]["state"] != "stuck"  # no goal of its own: it waits for its owner
    put_back = wait_for(lambda: sim.find(r"position slid ([0-9.]+) m with its odometry: put back"), timeout=10,
                        message="the position put back")
    assert float(put_back.group(1)) > 0.05  # it had slid into the wall...
    wait_for(lambda: abs(sim.pose()["y"] - _truth(sim)["y"]) < 0.05, timeout=10,
             message="...and is where the robot really is again")


def test_asked_to_back_out_it_does_slowly_and_then_goes_on_to_the_office(sim):
    events = EventReader(sim.url, kinds=["stuck"], timeout=120)
    assert events.next()[1]["state"] == "stuck"  # replayed: the last said (pressed)
    before = _truth(sim)
    r = sim.post("/stuck/back_out")
    assert r.status_code == 202 and r.json()["stuck"]["state"] in ("stuck", "backing_out"), r.text
    said = [events.next()[1] for _ in range(2)]
    assert [s["state"] for s in said] == ["backing_out", "free"], said
    assert said[0]["message"] == "Stuck near sofa: backing out 30 cm slowly."
    events.response.close()
    after = _truth(sim)
    assert before["y"] - after["y"] > 0.1  # straight back, off the wall it faced
    assert sim.post("/stuck/back_out").json()["error"] == "not_stuck"
    r = sim.post("/goto", {"name": "office", "wait": 120}, timeout=130)
    assert r.status_code == 200, r.text
    truth = _truth(sim)
    assert math.hypot(truth["x"] - OFFICE[0], truth["y"] - OFFICE[1]) < 0.3
    stuck = sim.status()["stuck"]
    assert stuck["state"] == "free" and stuck["count"] == 1 and stuck["freed"] == 1
