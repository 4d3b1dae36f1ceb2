"""Server configuration: dataclasses with defaults, loaded from one YAML file.

Every key has a default that suits the reference robot (Pi 4, two L298N
bridges, skid-steer, RPLIDAR A1), so an empty file, or no file at all, is a
valid configuration. Validation happens once, at start-up: a wrong type, a
value out of range or an unknown key (a typo must not silently fall back to a
default) raises :class:`~flask_move_server.errors.ConfigError` naming the
file, the key and the reason. Pure: imports neither rospy nor Flask.
"""

import dataclasses
import difflib
import logging
import math
import os
import re
import stat
import typing
from dataclasses import dataclass, field
from typing import Any, Dict, List, Literal, Optional, get_args, get_origin

import yaml

from flask_move_server.errors import ConfigError

log = logging.getLogger(__name__)

TOKEN_ENV = "FLASK_MOVE_SERVER_TOKEN"
LOOPBACK_HOSTS = ("127.0.0.1", "localhost", "::1")


def _positive(value):
    return None if value > 0 else "must be greater than 0"


def _non_negative(value):
    return None if value >= 0 else "must be 0 or more"


def _port(value):
    return None if 0 <= value <= 65535 else "must be a TCP port, 0 to 65535"


def _dns_label(value):
    if value.endswith(".local"):
        return "must be the name without .local ({!r}, not {!r})".format(value[: -len(".local")], value)
    valid = 0 < len(value) <= 63 and value[0] != "-" and value[-1] != "-" and all(
        c.isascii() and (c.isalnum() or c == "-") for c in value
    )
    return None if valid else "must be 1 to 63 letters, digits or '-' (not at either end), like robot"


def _instance_name(value):
    if "." in value:
        return "must not contain '.' (it separates DNS labels)"
    if 0 < len(value.encode("utf-8")) <= 63:
        return None
    return "must be 1 to 63 bytes of text"


def _host_names(value):
    for name in value:
        if name != "*" and not re.fullmatch(r"\.?[A-Za-z0-9_-]+(\.[A-Za-z0-9_-]+)*\.?", name):
            return "must list host names (robot.lan), domains (.lan) or '*', got {!r}".format(name)
    return None


def _speed_factor(value):
    return None if 0 < value <= 20 else "must be above 0 and at most 20 (simulated seconds per real second)"


def _check(check, **kw):
    return field(metadata={"check": check}, **kw)


def _path(**kw):
    return field(metadata={"path": True}, **kw)


@dataclass
class ServerConfig:
    """HTTP server: where it listens and who may use it."""

    host: str = "0.0.0.0"
    port: int = _check(_port, default=5000)
    token: Optional[str] = None
    token_file: Optional[str] = _path(default=None)
    insecure: bool = False
    threads: int = _check(_positive, default=6)
    max_body_bytes: int = _check(_positive, default=16384)
    static: bool = True
    allowed_hosts: List[str] = _check(_host_names, default_factory=list)
    connection_limit: int = _check(_positive, default=100)
    request_timeout: float = _check(_positive, default=10.0)
    channel_timeout: float = _check(_positive, default=30.0)


@dataclass
class WaypointsConfig:
    """Where the named places live."""

    file: str = _path(default="waypoints.yaml")
    lock_timeout: float = _check(_positive, default=3.0)


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
    master_check_period: float = _check(_positive, default=1.0)
    exit_on_new_master: bool = True
    frames: FramesConfig = field(default_factory=FramesConfig)


@dataclass
class NavigationConfig:
    """How goals reach the navigation stack."""

    goal_interface: Literal["action", "topic"] = "action"
    action: str = "move_base"
    simple_goal_topic: str = "move_base_simple/goal"
    amcl_pose_topic: str = "amcl_pose"
    server_wait: float = _check(_non_negative, default=0.2)
    max_wait: float = _check(_positive, default=600.0)
    pose_max_age: float = _check(_positive, default=2.0)


@dataclass
class TeleopConfig:
    """Velocity commands sent from ``POST /teleop``."""

    topic: str = "cmd_vel"
    max_linear: float = _check(_positive, default=0.4)
    max_angular: float = _check(_positive, default=1.5)
    deadman: float = _check(_positive, default=0.5)
    rate: float = _check(_positive, default=10.0)


def _fraction(value):
    return None if 0 <= value <= 1 else "must be between 0 and 1"


def _gpio(value):
    return None if value is None or 0 <= value <= 27 else "must be a BCM GPIO number, 0 to 27"


def _debounce(value):
    return None if 0 <= value <= 1 else "must be 0 to 1 seconds"


@dataclass
class MotorChannelConfig:
    """One L298N channel (a motor, or two in parallel): BCM pins and direction."""

    in1: Optional[int] = _check(_gpio, default=None)
    in2: Optional[int] = _check(_gpio, default=None)
    en: Optional[int] = _check(_gpio, default=None)
    invert: bool = False


def _channels(*pins):
    return field(default_factory=lambda: [MotorChannelConfig(*p) for p in pins])


@dataclass
class L298nConfig:
    """Two L298N bridges on the Pi's GPIO (BCM numbering); defaults in docs/wiring.md."""

    left: List[MotorChannelConfig] = _channels((17, 27, 22), (23, 24, 25))
    right: List[MotorChannelConfig] = _channels((12, 13, 19), (16, 20, 21))
    pwm_frequency: float = _check(_positive, default=200.0)
    stop_mode: Literal["brake", "coast"] = "brake"


@dataclass
class SerialDriveConfig:
    """A microcontroller speaking the ros_arduino_bridge protocol over pyserial."""

    port: str = "/dev/ttyACM0"
    baudrate: int = _check(_positive, default=57600)
    timeout: float = _check(_positive, default=0.2)
    pid_rate: float = _check(_positive, default=30.0)
    ticks_per_rev: float = _check(_positive, default=1920.0)
    open_delay: float = _check(_non_negative, default=2.0)
    reconnect_period: float = _check(_positive, default=1.0)
    keepalive: float = _check(_positive, default=0.5)


@dataclass
class DriveConfig:
    """The motor driver that turns ``/cmd_vel`` into wheel commands."""

    backend: Literal["none", "l298n", "serial", "sim"] = "none"
    cmd_vel_topic: str = "cmd_vel"
    odom_topic: str = "odom"
    cmd_vel_timeout: float = _check(_positive, default=0.5)
    odom_rate: float = _check(_positive, default=20.0)
    control_rate: float = _check(_positive, default=50.0)
    publish_tf: bool = True
    track_width: float = _check(_positive, default=0.2)
    track_multiplier: float = _check(_positive, default=1.0)
    wheel_radius: float = _check(_positive, default=0.0325)
    max_wheel_speed: float = _check(_positive, default=0.5)
    min_duty: float = _check(_fraction, default=0.3)
    max_duty: float = _check(_fraction, default=1.0)
    max_linear: float = _check(_positive, default=0.4)
    max_angular: float = _check(_positive, default=2.0)
    max_linear_accel: float = _check(_non_negative, default=1.0)
    max_angular_accel: float = _check(_non_negative, default=4.0)
    l298n: L298nConfig = field(default_factory=L298nConfig)
    serial: SerialDriveConfig = field(default_factory=SerialDriveConfig)
    estop_pin: Optional[int] = _check(_gpio, default=None)
    estop_debounce: float = _check(_debounce, default=0.02)


@dataclass
class MdnsConfig:
    """Advertising the robot as ``<hostname>.local`` with zeroconf (see docs/network.md)."""

    enabled: bool = True
    hostname: str = _check(_dns_label, default="robot")
    instance: Optional[str] = _check(_instance_name, default=None)
    publish_hostname: Literal["auto", "always", "never"] = "auto"
    address_check_period: float = _check(_positive, default=2.0)


@dataclass
class SimConfig:
    """The simulated robot and world used by ``--sim``."""

    enabled: bool = False
    map: Optional[str] = _path(default=None)
    speed_factor: float = _check(_speed_factor, default=1.0)
    robot_radius: float = _check(_positive, default=0.15)
    safety_margin: float = _check(_non_negative, default=0.1)
    rate: float = _check(_positive, default=50.0)
    scan_rate: float = _check(_non_negative, default=5.5)
    control_rate: float = _check(_positive, default=20.0)
    max_linear: float = _check(_positive, default=0.3)
    max_angular: float = _check(_positive, default=1.2)
    xy_goal_tolerance: float = _check(_positive, default=0.1)
    yaw_goal_tolerance: float = _check(_positive, default=0.2)
    stuck_timeout: float = _check(_positive, default=10.0)
    map_topic: str = "map"
    scan_topic: str = "scan"


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
    source: str = field(default="(defaults)", metadata={"internal": True})

    def resolved_token(self):
        """The bearer token in force: env var, then ``token``, then ``token_file``; None if none.

        Every source is stripped the same way (a file's newline or a pasted space is not part of
        the secret) and checked: empty or not printable ASCII is a ConfigError (see check_token).
        """
        found = self.token_source()
        if found is None:
            return None
        source, key, text = found
        return check_token(text.strip(), source, key)

    def token_source(self):
        """(source, key, raw text) of the token in force, or None; an empty env var counts as unset."""
        env = os.environ.get(TOKEN_ENV, "")
        if env.strip():
            return "environment", TOKEN_ENV, env
        if self.server.token is not None:
            return self.source, "server.token", self.server.token
        if self.server.token_file:
            return self.source, "server.token_file", _read_token_file(self.server.token_file, self.source)
        return None

    def serves_only_loopback(self):
        """True when the server binds a loopback address only."""
        return self.server.host in LOOPBACK_HOSTS


def _read_token_file(path, source):
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except OSError as exc:
        raise ConfigError(source, "server.token_file", "cannot read {}: {}".format(path, exc.strerror))
    except UnicodeDecodeError:
        raise ConfigError(source, "server.token_file", "{} is not text (UTF-8)".format(path))


def check_token(token, source, key):
    """``token`` if it can be a bearer token every client sends alike, else ConfigError.

    Non-ASCII is refused rather than half-supported: curl sends a header's bytes as typed (UTF-8),
    browsers and Python's http.client (requests, robotctl) send Latin-1, so such a token would
    work from some clients and not from others.
    """
    if not token:
        raise ConfigError(source, key, "the token is empty; set one, or remove the setting")
    bad = [i for i, c in enumerate(token) if not " " <= c <= "~"]
    if bad:
        raise ConfigError(source, key, "the token has a character that is not printable ASCII (at position {}); "
                          "HTTP clients would send it differently. Use letters, digits and punctuation, e.g. "
                          "python3 -c 'import secrets; print(secrets.token_urlsafe(24))'".format(bad[0] + 1))
    return token


def warn_if_token_file_shared(config):
    """Log a warning when the token in force comes from a file other users can read or change."""
    found = config.token_source()
    if found is None or found[1] != "server.token_file":
        return
    path = config.server.token_file
    mode = stat.S_IMODE(os.stat(path).st_mode)
    if mode & 0o077:
        log.warning("the token file %s can be read by other users of this machine (mode %04o): "
                    "run chmod 600 %s", path, mode, path)


def load(path=None):
    """Load and validate the config file at ``path`` (``None``: all defaults)."""
    if path is None:
        return Config()
    data = _read_yaml(path)
    base_dir = os.path.dirname(os.path.abspath(path))
    config = build(Config, data, source=str(path), base_dir=base_dir)
    config.source = str(path)
    return config


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


def build(cls, data, source="(config)", base_dir=".", prefix=""):
    """Build dataclass ``cls`` from the mapping ``data``, validating every key."""
    if not isinstance(data, dict):
        raise ConfigError(source, prefix.rstrip(".") or None, "must be a mapping, got {}".format(_kind(data)))
    fields = {f.name: f for f in dataclasses.fields(cls) if not f.metadata.get("internal")}
    hints = typing.get_type_hints(cls)
    unknown = [k for k in data if k not in fields]
    if unknown:
        key = str(unknown[0])
        close = difflib.get_close_matches(key, list(fields), n=1)
        hint = "; did you mean {!r}?".format(close[0]) if close else "; known keys: {}".format(", ".join(fields))
        raise ConfigError(source, prefix + key, "unknown key" + hint)
    values = {}
    for name, value in data.items():
        f = fields[name]
        key = prefix + name
        values[name] = _coerce(hints[name], value, source, key, base_dir)
        if value is not None and f.metadata.get("path"):
            values[name] = os.path.normpath(os.path.join(base_dir, os.path.expanduser(values[name])))
        check = f.metadata.get("check")
        problem = check(values[name]) if check and values[name] is not None else None
        if problem:
            raise ConfigError(source, key, "{} (got {!r})".format(problem, value))
    return cls(**values)


def _coerce(hint, value, source, key, base_dir):
    origin = get_origin(hint)
    if origin is typing.Union:
        inner = [a for a in get_args(hint) if a is not type(None)]
        return None if value is None else _coerce(inner[0], value, source, key, base_dir)
    if origin is Literal:
        choices = get_args(hint)
        if value not in choices:
            raise ConfigError(source, key, "must be one of {} (got {!r})".format(", ".join(choices), value))
        return value
    if origin in (list, List):
        if not isinstance(value, list):
            raise ConfigError(source, key, "must be a list, got {}".format(_kind(value)))
        (item,) = get_args(hint)
        return [_coerce(item, v, source, "{}[{}]".format(key, i), base_dir) for i, v in enumerate(value)]
    if origin in (dict, Dict):
        if not isinstance(value, dict):
            raise ConfigError(source, key, "must be a mapping, got {}".format(_kind(value)))
        return dict(value)
    if dataclasses.is_dataclass(hint):
        return build(hint, {} if value is None else value, source, base_dir, key + ".")
    return _scalar(hint, value, source, key)


def _scalar(hint, value, source, key):
    if hint is Any:
        return value
    if hint is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(source, key, "must be true or false, got {!r}".format(value))
    if hint is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise ConfigError(source, key, "must be a whole number, got {!r}".format(value))
    if hint is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
            return float(value)
        raise ConfigError(source, key, "must be a finite number, got {!r}".format(value))
    if hint is str:
        if isinstance(value, str):
            return value
        raise ConfigError(source, key, "must be text, got {!r}".format(value))
    raise ConfigError(source, key, "unsupported setting type {}".format(hint))


def _kind(value):
    return {dict: "a mapping", list: "a list", str: "text"}.get(type(value), repr(value))


def check_serving_policy(config):
    """At start-up: the token is valid and private; no network address is served without one (unless insecure)."""
    token = config.resolved_token()
    if token:
        warn_if_token_file_shared(config)
    if token or config.serves_only_loopback() or config.server.insecure:
        return
    raise ConfigError(
        config.source,
        "server.token",
        "refusing to serve {} without a token: anyone on the network could drive the robot. "
        "Set {}=<secret> or server.token / server.token_file in the config, "
        "bind --host 127.0.0.1, or pass --insecure on a trusted network".format(config.server.host, TOKEN_ENV),
    )


def as_plain(config):
    """The configuration as nested dicts, in the config file's shape."""
    data = dataclasses.asdict(config)
    data.pop("source", None)
    return data


def merge(base, override):
    """``base`` with ``override``'s keys laid over it, section by section."""
    result = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(result.get(key), dict):
            result[key] = merge(result[key], value)
        else:
            result[key] = value
    return result
