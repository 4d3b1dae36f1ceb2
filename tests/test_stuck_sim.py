"""A robot wedged on the office door's jamb in the demo flat says so and gets itself out:
``flask-move-server --sim``, one real server process for the module, its own master, real ROS.

Driven by the joystick into the jamb, the simulated robot's wheels turn and it does not move (the
sim's body stops at the wall; its odometry, like the L298N drive's, counts the commands): the server
says it is pressed against something, and its localized pose slides into the wall, as the real
robot's did (issue 33). Sent to the office from there, the move_base stand-in cannot plan, as navfn
cannot: the server notices at once, holds the goal, backs out slowly, asks localization to look
again, and sends the goal again, which arrives. Each change is a ``stuck`` event on ``GET /events``.
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


def test_pressed_on_the_jamb_by_the_joystick_it_says_so_within_seconds_and_its_pose_slides(sim):
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
    assert stuck["state"] == "stuck" and stuck["message"].startswith("Pressed against something near sofa")
    assert pressed_at is not None and time.monotonic() - pressed_at < 8.0  # within a few seconds
    assert not sim.status()["teleop"]["active"]  # it stopped pushing
    assert sim.status()["navigation"]["state"] != "stuck"  # no goal of its own: nothing to back out of
    assert sim.pose()["y"] - _truth(sim)["y"] > 0.05  # localized further on than it is: into the wall


def test_sent_on_from_there_it_backs_out_by_itself_and_arrives(sim):
    events = EventReader(sim.url, kinds=["stuck"], timeout=120)
    assert events.next()[1]["state"] == "stuck"  # replayed: the last said (pressed)
    r = sim.post("/goto", {"name": "office"})
    assert r.status_code == 202, r.text
    assert events.next()[1]["state"] == "free"  # a goal: what was said without one is over
    said = [events.next()[1] for _ in range(3)]
    assert [s["state"] for s in said] == ["stuck", "backing_out", "free"], said
    assert said[0]["message"].startswith("Stuck near sofa: it is localized with its footprint on a wall"), said
    assert said[1]["message"].startswith("Stuck near sofa: backing out")
    assert sim.find(r"aborting the goal: Failed to find a valid plan")  # as navfn, from a pose in the wall
    events.response.close()
    wait_for(lambda: sim.status()["navigation"]["state"] != "active", timeout=120, message="the goal's end")
    nav, truth = sim.status()["navigation"], _truth(sim)
    assert nav["state"] == "succeeded" and nav["target"] == "office", nav
    assert math.hypot(truth["x"] - OFFICE[0], truth["y"] - OFFICE[1]) < 0.3
    assert sim.find(r"goal \d+: backing out ended done")
    stuck = sim.status()["stuck"]
    assert stuck["state"] == "free" and stuck["count"] == 2 and stuck["freed"] == 1
    assert sim.find(r"goal \d+: sent again after backing out")
