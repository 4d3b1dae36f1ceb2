"""Server configuration: dataclasses with defaults, loaded from one YAML file.

Every key has a default that suits the reference robot (Pi 4, two L298N
bridges, skid-steer, RPLIDAR A1), so an empty file, or no file at all, is a
valid configuration. Validation happens once, at start-up: a wrong type, a
value out of range or an unknown key (a typo must not silently fall back to a
default) raises :class:`~flask_move_server.core.errors.ConfigError` naming the
file, the key and the reason. Pure: imports neither rospy nor Flask.

This module is the schema; the rules its values are checked by are config_rules.py, the generic
loader is typed_yaml.py, the token and the serving policy are access.py, and the motor backend
names come from the registry in drive/backends.
"""

import os
from dataclasses import dataclass, field
from typing import List, Literal, Optional

import yaml

from flask_move_server.config import access, rules
from flask_move_server.config.access import TOKEN_ENV, check_serving_policy  # noqa: F401 (config.<name> for the wiring)
from flask_move_server.config.typed_yaml import (  # noqa: F401 (as_plain, merge: config.<name> for the wiring)
    as_plain,
    build,
    checked,
    internal_field,
    merge,
    path_field,
)
from flask_move_server.core.errors import ConfigError
from flask_move_server.drive.backends import names as backend_names

# Every motor backend the registry knows (drive/backends), without importing any of them.
MotorBackendName = Literal[tuple(backend_names())]


@dataclass
class ServerConfig:
    """HTTP server: where it listens and who may use it."""

    host: str = "0.0.0.0"
    port: int = checked(rules.tcp_port, default=5000)
    token: Optional[str] = None
    token_file: Optional[str] = path_field(default=None)
    insecure: bool = False
    threads: int = checked(rules.positive, default=6)
    max_body_bytes: int = checked(rules.positive, default=16384)
    static: bool = True
    allowed_hosts: List[str] = checked(rules.host_names, default_factory=list)
    connection_limit: int = checked(rules.positive, default=100)
    connections_per_address: int = checked(rules.positive, default=32)
    request_timeout: float = checked(rules.positive, default=10.0)
    channel_timeout: float = checked(rules.positive, default=30.0)
    max_streams: int = checked(rules.positive, default=8)


@dataclass
class WaypointsConfig:
    """Where the named places live."""

    file: str = path_field(default="waypoints.yaml")
    lock_timeout: float = checked(rules.positive, default=3.0)


@dataclass
class FramesConfig:
    """tf frame names (REP-105)."""

    map: str = "map"
    odom: str = "odom"
    base_link: str = "base_link"


@dataclass
class RosConfig:
    """The rospy node and how the ROS master is watched."""

    node_name: str = "flask_move_server"
    master_check_period: float = checked(rules.positive, default=1.0)
    exit_on_new_master: bool = True
    frames: FramesConfig = field(default_factory=FramesConfig)


@dataclass
class NavigationConfig:
    """How goals reach the navigation stack."""

    goal_interface: Literal["action", "topic"] = "action"
    action: str = "move_base"
    simple_goal_topic: str = "move_base_simple/goal"
    amcl_pose_topic: str = "amcl_pose"
    plan_topic: str = "move_base/NavfnROS/plan"
    server_wait: float = checked(rules.non_negative, default=0.2)
    max_wait: float = checked(rules.positive, default=600.0)
    pose_max_age: float = checked(rules.positive, default=2.0)


@dataclass
class TeleopConfig:
    """Velocity commands sent from ``POST /teleop``."""

    topic: str = "cmd_vel"
    max_linear: float = checked(rules.positive, default=0.4)
    max_angular: float = checked(rules.positive, default=1.5)
    deadman: float = checked(rules.positive, default=0.5)
    rate: float = checked(rules.positive, default=10.0)


@dataclass
class MotorChannelConfig:
    """One L298N channel (a motor, or two in parallel): BCM pins and direction."""

    in1: Optional[int] = checked(rules.gpio_pin, default=None)
    in2: Optional[int] = checked(rules.gpio_pin, default=None)
    en: Optional[int] = checked(rules.gpio_pin, default=None)
    invert: bool = False


def _channels(*pins):
    return field(default_factory=lambda: [MotorChannelConfig(*p) for p in pins])


@dataclass
class L298nConfig:
    """Two L298N bridges on the Pi's GPIO (BCM numbering); defaults in docs/wiring.md."""

    left: List[MotorChannelConfig] = _channels((17, 27, 22), (23, 24, 25))
    right: List[MotorChannelConfig] = _channels((12, 13, 19), (16, 20, 21))
    pwm_frequency: float = checked(rules.positive, default=200.0)
    stop_mode: Literal["brake", "coast"] = "brake"


@dataclass
class SerialDriveConfig:
    """A microcontroller speaking the ros_arduino_bridge protocol over pyserial."""

    port: str = "/dev/ttyACM0"
    baudrate: int = checked(rules.positive, default=57600)
    timeout: float = checked(rules.positive, default=0.2)
    pid_rate: float = checked(rules.positive, default=30.0)
    ticks_per_rev: float = checked(rules.positive, default=1920.0)
    open_delay: float = checked(rules.non_negative, default=2.0)
    reconnect_period: float = checked(rules.positive, default=1.0)
    keepalive: float = checked(rules.positive, default=0.5)


@dataclass
class DriveConfig:
    """The motor driver that turns ``/cmd_vel`` into wheel commands."""

    backend: MotorBackendName = "none"
    cmd_vel_topic: str = "cmd_vel"
    odom_topic: str = "odom"
    cmd_vel_timeout: float = checked(rules.positive, default=0.5)
    odom_rate: float = checked(rules.positive, default=20.0)
    control_rate: float = checked(rules.positive, default=50.0)
    publish_tf: bool = True
    track_width: float = checked(rules.positive, default=0.2)
    track_multiplier: float = checked(rules.positive, default=1.0)
    wheel_radius: float = checked(rules.positive, default=0.0325)
    max_wheel_speed: float = checked(rules.positive, default=0.5)
    min_duty: float = checked(rules.fraction, default=0.3)
    max_duty: float = checked(rules.fraction, default=1.0)
    max_linear: float = checked(rules.positive, default=0.4)
    max_angular: float = checked(rules.positive, default=2.0)
    max_linear_accel: float = checked(rules.non_negative, default=1.0)
    max_angular_accel: float = checked(rules.non_negative, default=4.0)
    l298n: L298nConfig = field(default_factory=L298nConfig)
    serial: SerialDriveConfig = field(default_factory=SerialDriveConfig)
    estop_pin: Optional[int] = checked(rules.gpio_pin, default=None)
    estop_debounce: float = checked(rules.debounce_seconds, default=0.02)


@dataclass
class MdnsConfig:
    """Advertising the robot as ``<hostname>.local`` with zeroconf (see docs/network.md)."""

    enabled: bool = True
    hostname: str = checked(rules.dns_label, default="robot")
    instance: Optional[str] = checked(rules.instance_name, default=None)
    publish_hostname: Literal["auto", "always", "never"] = "auto"
    address_check_period: float = checked(rules.positive, default=2.0)


@dataclass
class SimConfig:
    """The simulated robot and world used by ``--sim``."""

    # The move_base stand-in drives with the robot's own move_base.yaml and dwa_local_planner.yaml.
    MOVED = {name: "the simulated move_base takes {} from {} in sim.navigation_config, the robot's own "
                   "navigation files (default: the shipped config/)".format(param, where)
             for name, param, where in (
                 ("max_linear", "max_vel_x", "dwa_local_planner.yaml"),
                 ("max_angular", "max_vel_theta", "dwa_local_planner.yaml"),
                 ("xy_goal_tolerance", "xy_goal_tolerance", "dwa_local_planner.yaml"),
                 ("yaw_goal_tolerance", "yaw_goal_tolerance", "dwa_local_planner.yaml"),
                 ("control_rate", "controller_frequency", "move_base.yaml"))}

    enabled: bool = False
    map: Optional[str] = path_field(default=None)
    speed_factor: float = checked(rules.speed_factor, default=1.0)
    robot_radius: float = checked(rules.positive, default=0.15)
    safety_margin: float = checked(rules.non_negative, default=0.1)
    rate: float = checked(rules.positive, default=50.0)
    scan_rate: float = checked(rules.non_negative, default=5.5)
    navigation_config: Optional[str] = path_field(default=None)  # None: the shipped config/ folder
    stuck_timeout: float = checked(rules.positive, default=10.0)
    battery_start: float = checked(rules.fraction, default=0.87)  # the simulated battery's charge at start
    map_topic: str = "map"
    scan_topic: str = "scan"
    laser_frame: str = "laser"


@dataclass
class MapsConfig:
    """Where maps live and how they are saved and drawn (docs/api.md, "Maps and modes")."""

    folder: Optional[str] = path_field(default=None)  # None: maps/ beside waypoints.file
    state_file: Optional[str] = path_field(default=None)  # None: mode.json beside waypoints.file
    topic: str = "map"
    save_timeout: float = checked(rules.positive, default=10.0)
    image_margin: float = checked(rules.non_negative, default=1.0)


@dataclass
class ModesConfig:
    """Who runs the navigation stack for the modes idle, mapping and navigation."""

    stack: Literal["auto", "roslaunch", "sim", "none"] = "auto"
    mapping_launch: str = checked(rules.launch_command, default="flask_move_server mapping.launch")
    navigation_launch: str = checked(rules.launch_command, default="flask_move_server navigation.launch")
    start_timeout: float = checked(rules.positive, default=60.0)
    stop_timeout: float = checked(rules.positive, default=10.0)
    restarts: int = checked(rules.non_negative, default=3)
    initial_pose_topic: str = "initialpose"


@dataclass
class DiagnosticsConfig:
    """The first-boot doctor (``GET /diagnostics``, ``robotctl doctor``): what it listens to, and how long."""

    window: float = checked(rules.positive, default=2.0)
    scan_topic: str = "scan"


@dataclass
class ExploreConfig:
    """The explorer (``POST /explore``): how much room the robot needs, and how long it may get nowhere."""

    robot_radius: float = checked(rules.positive, default=0.25)  # --sim: sim.robot_radius + sim.safety_margin
    progress_timeout: float = checked(rules.positive, default=30.0)


@dataclass
class StuckConfig:
    """A stuck robot: noticed from the laser and the goals' ends, said, and backed out (docs/commanding.md)."""

    enabled: bool = True
    back_out: bool = True  # back out by itself when a goal got it stuck and the laser shows room behind
    back_out_distance: float = checked(rules.positive, default=0.3)  # m at most, each time
    back_out_speed: float = checked(rules.positive, default=0.1)  # m/s: at or above what the drive can crawl at
    clearance: float = checked(rules.non_negative, default=0.05)  # m kept from what the laser sees behind
    tries: int = checked(rules.non_negative, default=2)  # back-outs for one goal before it ends stuck
    quick_abort: float = checked(rules.positive, default=20.0)  # s: a goal aborted sooner, not moving, counts


@dataclass
class DockConfig:
    """Docking onto the map's charger (docs/docking.md)."""

    staging_distance: float = checked(rules.positive, default=0.4)  # m before the dock move_base stops at
    approach_speed: float = checked(rules.positive, default=0.05)  # m/s onto the charger, straight
    retries: int = checked(rules.positive, default=3)  # tries onto the charger before it gives up
    return_below: float = checked(rules.fraction, default=0.2)  # go home below this charge (0..1)
    resume_above: float = checked(rules.fraction, default=0.8)  # a paused run goes on above this
    critical_below: float = checked(rules.fraction, default=0.1)  # goals other than home refused below
    charge_detect: Literal["battery", "gpio", "none"] = "battery"  # what says it charges
    charge_gpio: Optional[int] = checked(rules.gpio_pin, default=None)  # BCM pin, high while charging


WEBHOOK_EVENTS = ("arrived", "failed", "run_done", "estop", "explore_done", "stuck", "docked", "dock_failed",
                  "low_battery")


@dataclass
class HomeAssistantConfig:
    """Home Assistant's MQTT discovery (docs/home-assistant.md)."""

    enabled: bool = True
    discovery_prefix: str = checked(rules.mqtt_topic_part, default="homeassistant")


@dataclass
class Vda5050Config:
    """The VDA 5050 vehicle on the same MQTT connection (docs/fleet.md)."""

    enabled: bool = False
    version: Literal["2.0.0"] = "2.0.0"  # the protocol spoken (its major is the topics' v2)
    interface_name: str = checked(rules.mqtt_topic_part, default="uagv")
    manufacturer: str = checked(rules.mqtt_topic_part, default="flask-move-server")
    serial_number: Optional[str] = checked(rules.mqtt_topic_part, default=None)  # None: the robot's name


@dataclass
class MqttConfig:
    """One connection to the owner's MQTT broker (off by default: the server needs no broker)."""

    enabled: bool = False
    # The robot's name on the broker (topics, client id, Home Assistant's device); None: mdns.hostname, or
    # robot-<6 hex of its machine id> when that is left at the default "robot" (two robots must not share one).
    name: Optional[str] = checked(rules.mqtt_topic_part, default=None)
    host: str = "localhost"
    port: int = checked(rules.tcp_port, default=1883)
    username: Optional[str] = None
    password_file: Optional[str] = path_field(default=None)
    tls: bool = False
    ca_file: Optional[str] = path_field(default=None)  # None with tls: the system's certificates
    keepalive: int = checked(rules.positive, default=30)
    outbox: int = checked(rules.positive, default=200)
    home_assistant: HomeAssistantConfig = field(default_factory=HomeAssistantConfig)
    vda5050: Vda5050Config = field(default_factory=Vda5050Config)


@dataclass
class WebhookConfig:
    """One webhook: a JSON POST to ``url`` on each of ``events``."""

    url: str = checked(rules.web_url, default="")
    events: List[Literal[WEBHOOK_EVENTS]] = field(default_factory=lambda: list(WEBHOOK_EVENTS))
    secret: Optional[str] = None  # signs each body (X-Robot-Signature-256: sha256=HMAC); or from secret_file
    secret_file: Optional[str] = path_field(default=None)


@dataclass
class BatteryConfig:
    """Where the battery's charge is heard (``sensor_msgs/BatteryState``), when something publishes it."""

    topic: str = "battery_state"


@dataclass
class Config:
    """The whole server configuration, one section per concern."""

    server: ServerConfig = field(default_factory=ServerConfig)
    waypoints: WaypointsConfig = field(default_factory=WaypointsConfig)
    ros: RosConfig = field(default_factory=RosConfig)
    navigation: NavigationConfig = field(default_factory=NavigationConfig)
    teleop: TeleopConfig = field(default_factory=TeleopConfig)
    drive: DriveConfig = field(default_factory=DriveConfig)
    mdns: MdnsConfig = field(default_factory=MdnsConfig)
    sim: SimConfig = field(default_factory=SimConfig)
    maps: MapsConfig = field(default_factory=MapsConfig)
    modes: ModesConfig = field(default_factory=ModesConfig)
    diagnostics: DiagnosticsConfig = field(default_factory=DiagnosticsConfig)
    explore: ExploreConfig = field(default_factory=ExploreConfig)
    stuck: StuckConfig = field(default_factory=StuckConfig)
    dock: DockConfig = field(default_factory=DockConfig)
    mqtt: MqttConfig = field(default_factory=MqttConfig)
    webhooks: List[WebhookConfig] = field(default_factory=list)
    battery: BatteryConfig = field(default_factory=BatteryConfig)
    source: str = internal_field(default="(defaults)")

    def resolved_token(self):
        """The bearer token in force, or None (see access.resolved_token)."""
        return access.resolved_token(self)

    def state_folder(self):
        """The folder of the waypoints file: maps/ and mode.json live there unless configured."""
        return os.path.dirname(os.path.abspath(self.waypoints.file))

    def maps_folder(self):
        """Where NAME.yaml + NAME.pgm + NAME.waypoints.yaml live."""
        return self.maps.folder or os.path.join(self.state_folder(), "maps")

    def mode_state_file(self):
        """Where the mode and map to come back to after a restart are kept."""
        return self.maps.state_file or os.path.join(self.state_folder(), "mode.json")

    def stack_kind(self):
        """Who runs the navigation stack: ``sim`` with --sim, ``roslaunch`` or ``none``."""
        if self.modes.stack == "auto":
            return "sim" if self.sim.enabled else "roslaunch"
        return self.modes.stack

    def serves_only_loopback(self):
        """True when the server binds a loopback address only."""
        return access.serves_only_loopback(self)


def load(path=None):
    """Load and validate the config file at ``path`` (``None``: all defaults)."""
    if path is None:
        return Config()
    data = _read_yaml(path)
    base_dir = os.path.dirname(os.path.abspath(path))
    config = build(Config, data, source=str(path), base_dir=base_dir)
    config.source = str(path)
    _check_dock(config.dock, config.source)
    return config


def _check_dock(dock, source):
    """The dock's settings that only make sense together."""
    if dock.charge_detect == "gpio" and dock.charge_gpio is None:
        raise ConfigError(source, "dock.charge_gpio", "charge_detect: gpio needs the BCM pin the charge-detect "
                          "input is wired to")
    if not dock.critical_below <= dock.return_below < dock.resume_above:
        raise ConfigError(source, "dock.return_below", "must lie between critical_below ({}) and resume_above "
                          "({})".format(dock.critical_below, dock.resume_above))


def _read_yaml(path):
    try:
        with open(path, encoding="utf-8") as f:
            data = yaml.safe_load(f)
    except FileNotFoundError:
        raise ConfigError(path, None, "file not found")
    except OSError as exc:
        raise ConfigError(path, None, "cannot read: {}".format(exc.strerror))
    except yaml.YAMLError as exc:
        raise ConfigError(path, None, "not valid YAML: {}".format(_one_line(exc)))
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(path, None, "the top level must be a mapping of sections (server:, drive:, ...)")
    return data


def _one_line(exc):
    return " ".join(str(exc).split())


