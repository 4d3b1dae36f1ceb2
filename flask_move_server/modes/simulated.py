"""The navigation stack of ``--sim``: the modes idle, mapping and navigation, in-process on the server's node.

The stack backend the mode manager drives when ``modes.stack`` is ``sim``
(``start(mode, map_yaml_or_None, on_exit)``, ``stop()``, ``close()``, like
``launched.py``'s roslaunch children). Physics and the laser always run on the
TRUE world (``SimWorld``); a mode only changes what the robot knows:

- ``navigation``: map_server's stand-in publishes the map (a saved map's YAML,
  or None: the simulated world's own map, as ``--sim`` always did), the move_base
  stand-in plans on it, and the world's AMCL stand-in publishes ``map → odom``
  (perfect localization: the map frame is the world frame).
- ``mapping``: the robot knows nothing. A fresh simulated SLAM map covering the
  world plus ``MAPPING_MARGIN`` grows from scans (``SimMapping``, which publishes
  ``/map`` and ``map → odom`` in the world's place), and the move_base stand-in
  plans on it with unknown space traversable (move_base's ``allow_unknown``), so
  goals into the unknown are accepted, replanning when the map grows an obstacle
  across the path.
- ``idle``: no ``/map``, no ``map → odom``, and no move_base action server at
  all: the server's ``/health`` says move_base is unavailable and ``/goto``
  answers 503, exactly as on a robot whose stack is not running.

``stop()`` ends the goal under way (aborted) and takes every topic of the mode
away; the sim never dies by itself, so ``on_exit`` is kept but never called.
"""

import logging
import threading

from flask_move_server.core.errors import BadRequest, ConfigError, StackFailed
from flask_move_server.modes.targets import MODES

log = logging.getLogger(__name__)

MAPPING_MARGIN = 1.0  # m of canvas around the true map, so the SLAM map never clips the flat
CLIENT_WAIT = 2.0  # s: start() waits this long at most for move_base's clients (the navigator) to connect
MAX_SCAN_RATE = 11.0  # scans integrated per real second at most, however fast the sim runs


class SimulatedStack:
    """Runs one mode at a time on the simulation's world and move_base stand-in."""

    def __init__(self, config, node, world, move_base, own_map):
        self._config = config
        self._node = node
        self._world = world
        self._move_base = move_base
        self._own_map = own_map  # (path, OccupancyMap, Planner) of the simulated world's map
        self._lock = threading.Lock()
        self._parts = []
        self._closed = False
        self.mode = None
        self.map_yaml = None
        self.slam = None  # the SLAM map while mapping
        self.on_exit = None

    def start(self, mode, map_yaml=None, on_exit=None):
        """Run ``mode`` (navigation on ``map_yaml``, None: the world's own map); blocks until it runs.

        Starting the mode and map already running does nothing; ``stop()`` first to start afresh.
        Raises StackFailed when the map cannot be read or the node is not connected.
        """
        self.begin(mode, map_yaml, on_exit)
        timeout = self._config.modes.start_timeout
        if not self._node.wait_connected(timeout):
            raise StackFailed("The simulated {} mode could not start: no ROS master answered at {} within {} s."
                              .format(mode, self._node.master_uri, timeout))
        if mode != "idle" and not self._move_base.wait_clients(CLIENT_WAIT):
            log.warning("simulated stack: %s runs, but not every move_base client connected within %s s",
                        mode, CLIENT_WAIT)

    def begin(self, mode, map_yaml=None, on_exit=None):
        """As :meth:`start`, without waiting for the node: the parts set up when it connects."""
        if mode not in MODES:
            raise BadRequest("Unknown mode {!r}: use one of {}.".format(mode, ", ".join(MODES)))
        if map_yaml is not None and mode != "navigation":
            raise BadRequest("Only the navigation mode takes a map.")
        with self._lock:
            if self._closed:
                raise StackFailed("The simulation is shutting down.")
            self.on_exit = on_exit
            if self.mode == mode and self.map_yaml == map_yaml:
                return
            self._take_down()
            try:
                getattr(self, "_bring_up_" + mode)(map_yaml)
            except BaseException:
                self._take_down()
                raise
            self.mode, self.map_yaml = mode, map_yaml
        log.info("simulated stack: %s%s", mode, " on " + map_yaml if map_yaml else "")

    def stop(self):
        """End the mode: the goal under way is aborted, /map and map → odom stop, move_base goes. Idempotent."""
        with self._lock:
            self._take_down()

    def close(self):
        """Stop, and refuse any later start. Idempotent."""
        with self._lock:
            self._closed = True
            self._take_down()

    # the modes -----------------------------------------------------------------------

    def _bring_up_idle(self, map_yaml):
        """Nothing runs: the robot only has its odometry."""

    def _bring_up_navigation(self, map_yaml):
        from flask_move_server.sim.map_server import MapServerStandIn
        from flask_move_server.sim.nomotion import NoMotionUpdateStandIn

        grid, planner = self._navigation_map(map_yaml)
        self._parts.append(MapServerStandIn(self._node, grid, self._config.ros.frames.map,
                                            self._config.sim.map_topic))
        self._keep_out(grid, planner)
        self._parts.append(NoMotionUpdateStandIn(self._node, self._world))
        self._world.localizing.set()
        self._move_base.set_planner(planner)
        self._move_base.serve()

    def _keep_out(self, grid, plain):
        """The zones' mask over ``grid``, where the robot's costmap configuration reads it (sim/keepout.py)."""
        from flask_move_server.sim.keepout import KeepoutStandIn
        from flask_move_server.sim.runner import default_navigation_config
        from flask_move_server.zones import TOPIC
        from flask_move_server.zones.costmap_rules import obeys_zones

        sim = self._config.sim
        obeys, why = obeys_zones(sim.navigation_config or default_navigation_config(), TOPIC)
        if not obeys:
            log.warning("simulated move_base: the costmaps as configured do not read the zones on %s (%s), so "
                        "neither does the simulation: docs/zones.md", TOPIC, "; ".join(why))
            return
        self._parts.append(KeepoutStandIn(self._node, TOPIC, grid, self._move_base, sim.robot_radius,
                                          sim.safety_margin, plain))

    def _navigation_map(self, map_yaml):
        """(grid, planner) of ``map_yaml``, or of the world's own map for None; StackFailed if unreadable."""
        from flask_move_server.sim import costmap, occupancy, planner

        if map_yaml is None:
            return self._own_map[1], self._own_map[2]
        sim = self._config.sim
        try:
            grid = occupancy.load(map_yaml)
        except ConfigError as exc:
            raise StackFailed("The simulated navigation could not load the map: {}".format(exc)) from exc
        return grid, planner.Planner(costmap.Costmap(grid, sim.robot_radius, sim.safety_margin), navfn_start=True)

    def _bring_up_mapping(self, map_yaml):
        from flask_move_server.sim.mapping import SimMapping
        from flask_move_server.sim.slam import GrowingMapPlanner, SlamMap

        sim, cfg = self._config.sim, self._config
        self.slam = SlamMap.around(self._world.laser, margin=MAPPING_MARGIN)
        # The laser's scans per simulated second, but at most MAX_SCAN_RATE real ones (CPU: ~10 ms a scan).
        scan_rate = min((sim.scan_rate or 5.5) * sim.speed_factor, MAX_SCAN_RATE)
        self._parts.append(SimMapping(self._node, self.slam, self._world, cfg.ros.frames, map_topic=sim.map_topic,
                                      odom_topic=cfg.drive.odom_topic, scan_rate=scan_rate,
                                      publish_period=max(0.25, 1.0 / sim.speed_factor)))
        # One cell more than the body's radius: a wall's corner no beam has hit yet is missing from the SLAM
        # map, and a path drawn past it at the body's own radius scrapes the true corner and sticks there
        # (a real move_base keeps off it: its inflation reaches 0.6 m and its local costmap sees the corner).
        planner = GrowingMapPlanner(self.slam, sim.robot_radius + self.slam.resolution, sim.safety_margin)
        self._move_base.set_planner(planner)
        self._move_base.serve()

    def _take_down(self):
        """Abort the goal and withdraw move_base first (the robot stops), then the map and localization."""
        self._move_base.withdraw()
        self._world.localizing.clear()
        parts, self._parts = self._parts, []
        for part in reversed(parts):
            part.close()
        self.mode = self.map_yaml = self.slam = None
