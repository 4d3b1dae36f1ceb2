"""``dock/docking.py`` over a stand-in robot: what the state machine does when commands cross its worker.

The docking's own staging goal goes through ``Robot._send``, which stops the robot from inside the
send when the e-stop latched meanwhile (``_unless_latched_meanwhile`` → ``stop`` → ``_end_run`` →
``Docking.ended_by``): in the worker's own thread, while it holds its send lock. That must end the
docking, not hang the worker (and with it every later command that ends a docking).
"""

import threading

from flask_move_server.config import DockConfig
from flask_move_server.dock.docking import Docking
from flask_move_server.waypoints import make_waypoint
from tests.conftest import wait_for


class _Robot:
    """The facade's parts the docking uses; ``dock_goal`` stops the robot from within, as a latched e-stop does."""

    def __init__(self):
        self.docking = None
        self.estop = type("EStop", (), {"latched": False})()
        self.teleop_control = type("Teleop", (), {"end_command": lambda self: None,
                                                   "command": lambda self, *a, **k: None})()

    def refuse_motion(self, what):
        pass

    def check_zones(self, pose, target=None):
        pass  # no zones on this map

    def stop(self, reason="Stopped (POST /stop)."):
        self.docking.ended_by(reason)

    def dock_goal(self, goal):
        self.estop.latched = True
        self.stop("The e-stop was engaged (POST /estop).")  # Robot._unless_latched_meanwhile
        return 1

    def goal_end(self, seq, timeout):
        return "canceled", None


def test_the_e_stop_latched_as_the_staging_goal_is_sent_ends_the_docking_and_hangs_nothing():
    robot = _Robot()
    dock = make_waypoint("Ladestation", 0.0, 0.0, 0.0)
    docking = robot.docking = Docking(robot, DockConfig(), lambda: dock, lambda: None)
    docking.dock()
    said = wait_for(lambda: docking.status() if docking.status()["state"] != "going" else None, timeout=5,
                    message="the docking ended")
    assert said["state"] == "undocked" and said["message"] == "The e-stop was engaged (POST /estop)."
    ended = threading.Thread(target=docking.ended_by, args=("Stopped (POST /stop).",), daemon=True)
    ended.start()
    ended.join(2)
    assert not ended.is_alive(), "a later command hung on the docking's send lock"
