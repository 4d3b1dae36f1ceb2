"""The parts :class:`~flask_move_server.app.cli.Server` builds, one method each: maps, runs, the
explorer, happenings, MQTT and VDA 5050, the doctor, the reporter, mDNS, the robot and its trips,
modes, the e-stop button, the sim's own master. Each registers what must be closed on the
server's ExitStack (``stack``), so they close in reverse; ``cli.py`` keeps the lifecycle.
"""


import logging
import os

log = logging.getLogger("flask_move_server")


class ServerParts:
    """The building half of :class:`~flask_move_server.app.cli.Server` (a mixin of it)."""

    def _build_maps(self, stack, store):
        """The map in use (from the map topic), the maps folder, and the waypoints following the active map."""
        from flask_move_server.maps import configured
        from flask_move_server.maps.catalogue import MapCatalogue
        from flask_move_server.maps.service import MapService
        from flask_move_server.ros.map_source import MapSource

        cfg = self.config
        catalogue = MapCatalogue(cfg.maps_folder())
        for path in catalogue.remove_leftovers():
            log.info("removed %s, left by a map save that was interrupted", path)
        source = MapSource(self._node, cfg.maps.topic, self.events)
        stack.callback(source.close)
        self.maps = MapService(catalogue, store, source, modes=getattr(self, "modes", None), events=self.events,
                               margin=cfg.maps.image_margin, save_timeout=cfg.maps.save_timeout,
                               configured=configured.of_config(cfg))
        return self.maps

    def _build_runs(self, stack, robot, store):
        """The one executor of runs (routes from the API, the page, schedules), its history in ``runs.json``
        of the state folder, and the scheduler feeding it; closed before the robot, leaving a run under way
        ``interrupted``."""
        from flask_move_server.missions.executor import RunExecutor
        from flask_move_server.missions.history import RunHistory, default_path
        from flask_move_server.missions.scheduler import Scheduler

        history = RunHistory(default_path(self.config.state_folder()))
        runs = RunExecutor(robot, store, history, events=self.events, modes=self.modes)
        stack.callback(runs.close)
        scheduler = Scheduler(store.routes, runs.scheduled)  # the active map's routes, asked afresh each minute
        stack.callback(scheduler.close)  # closed first: no run starts while the server stops
        scheduler.start()
        robot.runs = runs
        self.runs = runs
        return runs

    def _build_explorer(self, stack, robot):
        """The explorer (``POST /explore``) over the mode manager and the map service; closed before the robot."""
        from flask_move_server.explore.explorer import Explorer

        cfg = self.config
        # Room kept from walls: the sim's robot and its costmap's safety margin, as the stand-in plans with.
        radius = cfg.sim.robot_radius + cfg.sim.safety_margin if cfg.sim.enabled else cfg.explore.robot_radius
        explorer = Explorer(robot, self.modes, self.maps, radius, events=self.events,
                            progress_timeout=cfg.explore.progress_timeout, start_timeout=cfg.modes.start_timeout)
        stack.callback(explorer.close)
        robot.explorer = explorer
        return explorer

    def _build_recovery(self, stack, robot, store):
        """The stuck watch (``stuck``): a stuck robot noticed from the laser and the goals' ends, said,
        backed out (``recovery/``); closed before the robot."""
        cfg = self.config
        if not cfg.stuck.enabled:
            return None
        from flask_move_server.core.errors import MoveServerError
        from flask_move_server.recovery import footprint
        from flask_move_server.recovery.recovery import Recovery
        from flask_move_server.recovery.watch import StuckWatch
        from flask_move_server.ros.relocalize import NoMotionUpdate
        from flask_move_server.sim.runner import default_navigation_config

        def grid():
            try:
                return self.maps.source.current()[1]
            except MoveServerError:
                return None

        polygon = footprint.read(cfg.sim.navigation_config or default_navigation_config())
        recovery = Recovery(robot, cfg.stuck, polygon, places=store.all, grid=grid, relocalize=NoMotionUpdate(),
                            events=self.events, set_pose=self.initial_pose.publish)
        stack.callback(recovery.close)
        watch = StuckWatch(recovery, self._node, robot, cfg.diagnostics.scan_topic, cfg.drive.odom_topic,
                           cfg.ros.frames.base_link)
        stack.callback(watch.start().close)
        robot.recovery = recovery
        return recovery

    def _build_zones(self, stack, robot, store):
        """The active map's zones: goals refused in them, and their mask on ``keepout_map`` (``zones/``)."""
        from flask_move_server.recovery import footprint
        from flask_move_server.ros.keepout import KeepoutPublisher
        from flask_move_server.sim.runner import default_navigation_config
        from flask_move_server.zones.guard import ZoneGuard

        polygon = footprint.read(self.config.sim.navigation_config or default_navigation_config())
        guard = ZoneGuard(store, footprint.inscribed_radius(polygon), footprint.circumscribed_radius(polygon))
        robot.zones = guard

        def pose():
            reading = robot.pose.current() if self._node.connected else None
            return reading.pose if reading is not None else None
        keepout = KeepoutPublisher(self._node, store, self.maps.source, guard, pose, events=self.events)
        stack.callback(keepout.close)
        self.keepout = keepout
        return guard

    def _build_docking(self, stack, robot, store):
        """Docking onto the active map's charger (``dock/``); closed before the robot."""
        from flask_move_server.dock.charge_signal import signal_of
        from flask_move_server.dock.docking import Docking

        cfg = self.config
        charge = signal_of(cfg.dock, robot.battery)
        if hasattr(charge, "close"):
            stack.callback(charge.close)
        docking = Docking(robot, cfg.dock, store.dock, charge, events=self.events,
                          room_ahead=self._room_ahead(robot), level=lambda: _charge_level(robot))
        stack.callback(docking.close)
        robot.docking = docking
        return docking

    def _go_home_when_low(self, stack, robot, runs, happenings):
        """Below ``dock.return_below`` the robot docks, a run paused, and goes on once charged (``dock/``)."""
        from flask_move_server.dock.low_battery import LowBattery

        low = LowBattery(robot, robot.docking, runs, self.config.dock, tell=happenings.low_battery)
        runs.holds_new_runs = low  # a run started while it goes home to charge begins paused
        stack.callback(low.start().close)

    def _room_ahead(self, robot):
        """``room_ahead(reach)``: metres the laser shows clear before the footprint (the stuck watch's latest
        scan), or None without one."""
        recovery = robot.recovery
        if recovery is None:
            return None
        from flask_move_server.recovery import footprint

        def room_ahead(reach):
            points = recovery.sensing.points(1.0) if recovery.sensing is not None else None
            if not points:
                return None
            return footprint.room_along(points, recovery.footprint, reach, 0.0, way=1)
        return room_ahead

    def _build_happenings(self, stack, robot):
        """What the robot did, by name (arrived, failed, run_done, estop, explore_done), for MQTT and for
        the webhooks ``webhooks:`` lists (POSTed from a queue of their own); both closed before the robot."""
        from flask_move_server.core.happenings import Happenings

        happenings = Happenings(robot, self.events)
        stack.callback(happenings.close)
        if self.config.webhooks:
            from flask_move_server.mqtt.webhooks import Webhooks

            webhooks = Webhooks(self.config.webhooks, self.config.mdns.hostname, happenings)
            stack.callback(webhooks.close)
        return happenings

    def _build_mqtt(self, stack, app, store):
        """The robot on the owner's MQTT broker (``mqtt.enabled``): Home Assistant's discovery, its
        commands and the state topic, on one connection made in the background; None when off."""
        cfg = self.config
        if not cfg.mqtt.enabled:
            return None
        from flask_move_server.mqtt.commands import Commands
        from flask_move_server.mqtt.ha_events import HaEvents
        from flask_move_server.mqtt.home_assistant import HomeAssistant, device_info
        from flask_move_server.mqtt.identity import broker_name
        from flask_move_server.mqtt.link import MqttLink
        from flask_move_server.mqtt.robot_state import RobotState

        name = broker_name(cfg.mqtt.name, cfg.mdns.hostname)
        if name != cfg.mdns.hostname and not cfg.mqtt.name:
            log.info("MQTT: this robot is '%s' on the broker (mdns.hostname is left at '%s', which other robots "
                     "share; from this machine's id, the same at every start; mqtt.name chooses another)", name,
                     cfg.mdns.hostname)
        link = MqttLink(cfg.mqtt, name)
        stack.callback(link.close)  # closed after the parts publishing on it: "offline" is the last word
        url = "http://{}.local:{}/".format(cfg.mdns.hostname, self.port)
        vehicle = self._build_vda5050(stack, link, store, name) if cfg.mqtt.vda5050.enabled else None
        shown_as = cfg.mdns.instance or cfg.mdns.hostname  # Home Assistant's device: the owner's name for it
        home = HomeAssistant(link, cfg.mqtt.home_assistant, name, device_info(name, shown_as, url), store,
                             self.events, vda_connection=vehicle.topic("connection") if vehicle else None)
        commands = Commands(link, self.robot, store, self.runs, changed=lambda: state.changed())
        happenings = self.happenings
        state = RobotState(link, self.robot, self.modes, self.runs, self.explorer, self.events,
                           refused=lambda: commands.refused, battery_heard=home.battery_heard,
                           last_reached=lambda: (happenings.last_reached or {}).get("name"), zones=store.zones)
        happenings.listen(lambda name, data: state.changed())  # a goal's end told at once, not a second later
        HaEvents(link, happenings)  # an arrival and a run's end as Home Assistant's events
        for part in (home, state):
            stack.callback(part.start().close)
        app.extensions["flask_move_server"]["mqtt"] = link
        self._tell_trust(app, link)
        return link.start()

    def _tell_trust(self, app, link):
        """Who can drive the robot through the broker: a warning at start when HTTP's token does not guard
        MQTT too, and the doctor's ``mqtt_access`` and ``mqtt_identity`` lines (docs/home-assistant.md)."""
        from flask_move_server.diagnostics.checks import WARN
        from flask_move_server.mqtt.trust import access_check, mqtt_checks

        guarded = bool(self.config.resolved_token())
        check = access_check(self.config.mqtt, guarded)
        if check.level == WARN:
            log.warning("MQTT: %s. %s", check.summary, check.advice)
        doctor = app.extensions["flask_move_server"].get("doctor")
        if doctor is not None:
            doctor.add_checks(lambda: mqtt_checks(link, guarded))

    def _build_vda5050(self, stack, link, store, name):
        """The robot as a VDA 5050 vehicle on ``link`` (docs/fleet.md): orders run on the run executor."""
        from flask_move_server.recovery import footprint
        from flask_move_server.sim.dwa import load as planner_limits
        from flask_move_server.sim.runner import default_map, default_navigation_config
        from flask_move_server.vda5050 import messages
        from flask_move_server.vda5050.vehicle import Vehicle

        cfg = self.config
        folder = cfg.sim.navigation_config or default_navigation_config()
        factsheet = messages.factsheet(cfg.mdns.hostname, planner_limits(folder), footprint.read_polygon(folder))
        own_map = os.path.splitext(os.path.basename(cfg.sim.map or default_map()))[0] if cfg.sim.enabled else "default"
        vehicle = Vehicle(link, cfg.mqtt.vda5050, name, self.robot, self.runs, store, self.modes,
                          factsheet, own_map=own_map)
        stack.callback(vehicle.start().close)
        return vehicle

    def _build_doctor(self, robot):
        """The first-boot doctor: ROS as the server's node sees it, and this machine."""
        from flask_move_server.diagnostics.doctor import Doctor
        from flask_move_server.ros.observe import RosObserver

        cfg = self.config
        topics = (cfg.diagnostics.scan_topic, cfg.drive.odom_topic, cfg.navigation.amcl_pose_topic)
        maps = getattr(self, "maps", None)
        observer = RosObserver(self._node, cfg.ros.frames, topics, robot.pose, robot.navigator,
                               map_source=maps.source if maps is not None else None)
        return Doctor(observer, self.modes, cfg.maps_folder(), cfg.diagnostics.window, simulated=cfg.sim.enabled)

    def _report(self, stack, robot):
        """The robot's state (pose, status, e-stop, move_base's plan, the laser scan) told on the event bus
        for GET /events."""
        from flask_move_server.core.reporter import Reporter
        from flask_move_server.ros.plan import PlanRelay
        from flask_move_server.ros.scan import ScanRelay

        cfg = self.config
        stack.callback(PlanRelay(cfg.navigation.plan_topic, self.events, self._node).close)
        scan = ScanRelay(cfg.diagnostics.scan_topic, cfg.ros.frames.map, self.events, self._node,
                         lambda: robot.pose.buffer)
        stack.callback(scan.start().close)
        stack.callback(Reporter(robot, self.events).start().close)

    def _advertise(self, stack):
        """Announce the API over mDNS with the real port; withdrawn first on close (goodbye packets)."""
        if not self.config.mdns.enabled:
            log.info("mDNS advertising is off (--no-mdns or mdns.enabled: false)")
            return
        if self.config.serves_only_loopback():
            log.info("serving %s only: not advertising over mDNS", self.config.server.host)
            return
        from flask_move_server.lan.mdns import Advertiser

        token_required = bool(self.config.resolved_token())
        advertiser = Advertiser(self.config.mdns, self.config.server.host, self.port, token_required)
        stack.callback(advertiser.close)
        advertiser.start()

    def _build_robot(self, stack, store):
        from flask_move_server.drive import make_drive
        from flask_move_server.drive.estop import EStop
        from flask_move_server.ros.node import RosNode

        cfg = self.config
        if cfg.sim.enabled:
            self._own_master(stack)
        node = RosNode(cfg.ros.node_name, cfg.ros.master_check_period, cfg.ros.exit_on_new_master, self.fatal)
        stack.callback(node.close)
        estop = EStop()
        drive = make_drive(cfg.drive, node, cfg.ros.frames, source=cfg.source, estop=estop)
        stack.callback(drive.close)  # SIGTERM → ExitStack → motors stopped, pins released
        if cfg.sim.enabled:
            from flask_move_server.sim.runner import Simulation

            # With the sim as the modes' stack, the mode manager's restore() starts the mode.
            self._simulation = Simulation(cfg, node, drive, autostart=cfg.stack_kind() != "sim",
                                          dock=lambda: dock_position(store))
            stack.callback(self._simulation.close)
        robot = build_robot(cfg, node, drive, estop)
        if self._simulation is not None:
            robot.ground_truth = self._simulation.world.pose
        stack.callback(robot.close)
        self._keep_trips(stack, robot)
        self._watch_estop_button(stack, estop)
        self._node = node
        self.robot = robot
        return robot

    def _keep_trips(self, stack, robot):
        """The goal under way kept in ``trip.json`` of the state folder: after a restart, the
        navigation status says which trip was interrupted (the robot does not resume it)."""
        from flask_move_server.core.trip_record import TripRecord

        trips = TripRecord(os.path.join(self.config.state_folder(), "trip.json"))
        stack.callback(trips.close)
        interrupted = trips.left_over()
        if interrupted:
            log.info("%s", interrupted)
            robot.navigator.set_aside(interrupted)
        robot.navigator.trips = trips

    def _build_modes(self, stack):
        """The mode manager over the backend ``modes.stack`` names; closed (its stack stopped) before the robot."""
        from flask_move_server.modes.manager import ModeManager
        from flask_move_server.ros.initial_pose import InitialPose

        cfg = self.config
        initial_pose = self.initial_pose = InitialPose(cfg.modes.initial_pose_topic, cfg.ros.frames.map, self._node)
        stack.callback(initial_pose.close)
        backend = self._stack_backend()
        if backend is None:
            log.info("modes: the navigation stack is started outside this server (modes.stack: %s)", cfg.modes.stack)
        modes = ModeManager(cfg, backend, self.events, relocalize=initial_pose.publish,
                            goals_ready=lambda: self.robot.navigator.server_ready())
        stack.callback(modes.close)
        if backend is not None:
            from flask_move_server.modes.goal_gate import GoalGate

            self.robot.goal_gate = GoalGate(modes, self.robot.navigator)
        return modes

    def _stack_backend(self):
        """Who runs the modes' stacks: the simulation's (``sim``), roslaunch children (``roslaunch``), or None."""
        kind = self.config.stack_kind()
        if kind == "sim":
            return getattr(self._simulation, "stacks", None)  # modes/simulated.py, built by the Simulation
        if kind == "roslaunch":
            from flask_move_server.modes.launched import LaunchedStack

            return self._stack.enter_context(LaunchedStack.from_config(self.config))  # closed after the manager
        return None

    def _watch_estop_button(self, stack, estop):
        """``drive.estop_pin``: a press of the physical e-stop button latches ``estop``."""
        if self.config.drive.estop_pin is None:
            return
        from flask_move_server.drive.estop_button import EStopButton

        stack.callback(EStopButton(self.config.drive, estop, source=self.config.source).close)

    def _own_master(self, stack):
        """``--sim``: start a ROS master when none answers at ROS_MASTER_URI; it is stopped last."""
        from flask_move_server.sim.runner import OwnMaster

        own = OwnMaster.ensure()
        if own is not None:
            stack.callback(own.close)


def build_robot(config, node, drive, estop=None):
    """The Robot facade over ``node``: pose tracker, navigator, teleop, ``drive``, the e-stop latch, the battery."""
    from flask_move_server.core.robot import Robot
    from flask_move_server.ros.battery import BatteryMonitor
    from flask_move_server.ros.navigator import Navigator
    from flask_move_server.ros.pose import PoseTracker
    from flask_move_server.ros.teleop import Teleop

    pose = PoseTracker(config.ros.frames, config.navigation.amcl_pose_topic, node, config.navigation.pose_max_age)
    navigator = Navigator(config.navigation, config.ros.frames, node, pose)
    teleop = Teleop(config.teleop, node)
    battery = BatteryMonitor(config.battery.topic, node)
    return Robot(node, navigator, pose, teleop, drive, estop, battery)


def _charge_level(robot):
    """The battery's charge 0..1, or None when unknown."""
    battery = robot.battery_status()
    return battery["percentage"] / 100.0 if battery and battery.get("percentage") is not None else None


def dock_position(store):
    """The Pose2D of the dock of the waypoints in use (the active map's), or None without one."""
    from flask_move_server.core.geometry import Pose2D

    dock = store.dock()
    return Pose2D(dock.x, dock.y, dock.yaw) if dock is not None else None
