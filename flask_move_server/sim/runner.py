"""Wiring of ``--sim``: the ROS master the simulation may own, and the simulation itself.

Everything runs inside the server process and shares its rospy node (rospy
allows one per process): the world and the move_base stand-in set up their
topics when the node connects (``RosNode.when_ready``), exactly like the
navigator and the base controller. ``cli`` builds them after the drive, so
they read the sim backend the base controller drives.
"""

import logging
import os
import shutil
import subprocess
import time
from urllib.parse import urlparse

from flask_move_server.core.errors import ConfigError
from flask_move_server.core.geometry import Pose2D
from flask_move_server.process.children import die_with_parent
from flask_move_server.ros import master
from flask_move_server.sim.demo_map import default_map, default_navigation_config

log = logging.getLogger(__name__)

LOCAL_HOSTS = ("localhost", "127.0.0.1", "::1", "")


class Simulation:
    """The simulated world, the move_base stand-in and the modes' stack, built on the server's node and drive.

    ``stacks`` is the stack backend of the modes (``modes/simulated.py``) for the
    mode manager. With ``autostart`` (the default) the simulation begins in
    navigation on its own map, as ``--sim`` always did; a mode manager that
    restores a mode itself passes ``autostart=False``, so nothing runs until it
    calls ``stacks.start``.

    With ``modes.stack: roslaunch`` (``world_only``) the simulation is the world alone: the robot's
    physics, ``/scan`` in the laser's frame and the laser's static tf, with the drive's own
    ``/odom`` and tf. No move_base, AMCL, SLAM or map_server stand-in: the shipped launch files
    start the real ones (on a PC with ROS Noetic's navigation packages), ``lidar:=false``.

    In both, the robot's battery (``sim/battery.py``) publishes on ``battery.topic``; ``dock()``
    says where the dock is (a Pose2D), or None: the battery charges on it.
    """

    def __init__(self, config, node, drive, autostart=True, dock=None):
        from flask_move_server.modes.simulated import SimulatedStack
        from flask_move_server.sim import costmap, laser, occupancy, planner
        from flask_move_server.sim.battery import BatteryModel, SimBattery
        from flask_move_server.sim.body import RobotBody
        from flask_move_server.sim.move_base import MoveBaseStandIn
        from flask_move_server.sim.world import SimWorld

        sim = config.sim
        wheel_speeds = getattr(getattr(drive, "backend", None), "wheel_speeds", None)
        if wheel_speeds is None:
            raise ConfigError(config.source, "drive.backend",
                              "--sim needs the sim motor backend (got {!r})".format(config.drive.backend))
        self.map_path = sim.map or default_map()
        grid = occupancy.load(self.map_path)
        self.costmap = costmap.Costmap(grid, sim.robot_radius, sim.safety_margin)
        track = config.drive.track_width * config.drive.track_multiplier
        self.body = RobotBody(self.costmap, track, Pose2D(0.0, 0.0, 0.0))
        if self.costmap.lethal_at(0.0, 0.0):
            raise ConfigError(self.map_path, "origin", "the robot starts at x=0, y=0 of the map frame, "
                              "which is in or too close to an obstacle (or off the map)")
        self.world_only = config.stack_kind() == "roslaunch"
        self.world = SimWorld(config, node, self.body, laser.Laser(grid), wheel_speeds,
                              stand_ins=not self.world_only)
        self.battery = SimBattery(config.battery.topic, node, wheel_speeds, self.world.pose, dock or (lambda: None),
                                  self.world.clock.now, BatteryModel(sim.battery_start))
        self.move_base = self.stacks = None
        if self.world_only:
            log.info("simulated world only: the navigation stack is the launch files' (modes.stack: roslaunch)")
            return
        own_planner = planner.Planner(self.costmap, navfn_start=True)
        self.move_base = MoveBaseStandIn(
            sim, config.navigation.action, config.drive.cmd_vel_topic, config.navigation.simple_goal_topic,
            config.ros.frames, node, own_planner, planner_limits(sim), self.world.believed_pose,
            plan_topic=config.navigation.plan_topic, serve=False, odom_topic=config.drive.odom_topic,
            clock=self.world.clock.now)
        self.stacks = SimulatedStack(config, node, self.world, self.move_base, (self.map_path, grid, own_planner))
        if autostart:
            self.stacks.begin("navigation", None)

    def close(self):
        """Stop the mode, the stand-in, the battery, then the world. Idempotent."""
        for part in (self.stacks, self.move_base, self.battery, self.world):
            if part is not None:
                part.close()


def planner_limits(sim):
    """The robot's own DWA limits (move_base.yaml + dwa_local_planner.yaml), which the stand-in obeys."""
    from flask_move_server.sim import dwa

    folder = sim.navigation_config or default_navigation_config()
    try:
        return dwa.load(folder)
    except OSError as exc:
        raise ConfigError(exc.filename or folder, None, "sim.navigation_config: cannot read the navigation "
                          "config the simulated move_base drives by: {}".format(exc.strerror))
    except (TypeError, ValueError, AttributeError) as exc:
        raise ConfigError(folder, None, "sim.navigation_config: not a move_base / DWA configuration: {}".format(exc))


class OwnMaster:
    """A ``rosmaster --core`` this process started because none answered; stopped on close."""

    def __init__(self, uri, process):
        self.uri = uri
        self.process = process

    @classmethod
    def ensure(cls, uri=None, timeout=10.0):
        """None when a master answers at ``uri``; otherwise start one there and return it."""
        uri = uri or master.master_uri()
        if master.identity("/flask_move_server_sim", uri, timeout=1.0) is not None:
            log.info("using the ROS master at %s", uri)
            return None
        parsed = urlparse(uri)
        if parsed.hostname not in LOCAL_HOSTS:
            raise ConfigError("ROS_MASTER_URI", None, "no ROS master answers at {} and it is not on this "
                              "machine, so --sim cannot start one there".format(uri))
        os.environ.setdefault("ROS_MASTER_URI", uri)
        if not (os.environ.get("ROS_IP") or os.environ.get("ROS_HOSTNAME")):
            os.environ["ROS_HOSTNAME"] = "localhost"  # a node URI that resolves without DNS
        rosmaster = shutil.which("rosmaster") or "rosmaster"
        process = subprocess.Popen([rosmaster, "--core", "-p", str(parsed.port or 11311)],
                                   stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                   start_new_session=True, preexec_fn=die_with_parent)
        own = cls(uri, process)
        own._wait_ready(timeout)
        log.info("started a ROS master at %s (pid %d); it stops with the server", uri, process.pid)
        return own

    def _wait_ready(self, timeout):
        deadline = time.monotonic() + timeout
        while master.identity("/flask_move_server_sim", self.uri, timeout=0.5) is None:
            if self.process.poll() is not None or time.monotonic() > deadline:
                self.close()
                raise ConfigError("ROS_MASTER_URI", None, "could not start a ROS master at {} "
                                  "(is the port taken, or rosmaster not installed?)".format(self.uri))
            time.sleep(0.1)

    def close(self):
        """Stop the master (SIGTERM, then SIGKILL after 3 s). Idempotent."""
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(3)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
            log.info("stopped the ROS master at %s", self.uri)

