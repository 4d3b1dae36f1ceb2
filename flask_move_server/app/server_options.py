"""``flask-move-server``'s command line, and the one config it makes with the file and ROS params.

The order in which settings win: the config file (``--config``), then ROS private params when
started by roslaunch (``_port:=…``), then the command-line flags. ``--sim`` also serves on
127.0.0.1 and drives the ``sim`` motor backend unless ``--host`` or ``--motor-backend`` say
otherwise. The serving policy (no token on a network address without ``--insecure``) is checked
last, on the result.
"""

import argparse
import os

from flask_move_server import __version__
from flask_move_server import config as config_mod
from flask_move_server.app.launching import LOG_LEVELS, apply_private_params, ros_node_name
from flask_move_server.core.errors import ConfigError
from flask_move_server.drive.backends import names as motor_backend_names


def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog="flask-move-server",
        description="Serve the HTTP API that sends a ROS 1 robot to named waypoints.",
    )
    parser.add_argument("--config", metavar="FILE", help="server config (YAML); default: built-in defaults")
    parser.add_argument("--waypoints", metavar="FILE", help="waypoints file (default: waypoints.file in the config)")
    parser.add_argument("--host", help="address to listen on (default 0.0.0.0; 127.0.0.1 with --sim)")
    parser.add_argument("--port", type=int, help="TCP port (default 5000); 0 picks a free one and logs it")
    parser.add_argument("--motor-backend", choices=motor_backend_names(), help="motor driver")
    parser.add_argument("--no-mdns", action="store_true", help="do not advertise robot.local over mDNS")
    parser.add_argument("--insecure", action="store_true", help="allow serving the network without a token")
    parser.add_argument("--sim", action="store_true", help="run a simulated robot and world (no hardware)")
    parser.add_argument("--mqtt", metavar="HOST[:PORT]",
                        help="join this MQTT broker (Home Assistant, docs/home-assistant.md): mqtt.enabled with its "
                             "host and port (1883 unless given); user and TLS come from the config")
    parser.add_argument("--map", metavar="MAP.yaml", help="with --sim: the map_server map to simulate")
    parser.add_argument("--log-level", default="INFO", choices=LOG_LEVELS)
    parser.add_argument("--version", action="version", version="%(prog)s " + __version__)
    return parser.parse_args(argv)


def load_config(args, ros_args):
    """The config file, then ROS private params (under roslaunch), then command-line flags."""
    config = config_mod.load(args.config)
    node_name = ros_node_name(ros_args)
    if node_name:
        config = apply_private_params(config, node_name)
    _apply_flags(config, args)
    config_mod.check_serving_policy(config)
    return config


def _apply_flags(config, args):
    if args.waypoints:
        config.waypoints.file = os.path.abspath(args.waypoints)
    if args.sim:
        config.sim.enabled = True
        if args.host is None:  # the simulated robot is this machine's only, unless --host says otherwise
            config.server.host = "127.0.0.1"
        if args.motor_backend is None:
            config.drive.backend = "sim"
    if args.map:
        config.sim.map = os.path.abspath(args.map)
    if args.host is not None:
        config.server.host = args.host
    if args.port is not None:
        if not 0 <= args.port <= 65535:
            raise ConfigError("--port", None, "must be a TCP port, 0 to 65535")
        config.server.port = args.port
    if args.motor_backend:
        config.drive.backend = args.motor_backend
    if args.no_mdns:
        config.mdns.enabled = False
    if args.insecure:
        config.server.insecure = True
    if args.mqtt:
        _apply_mqtt(config.mqtt, args.mqtt)


def _apply_mqtt(mqtt, broker):
    """``--mqtt HOST[:PORT]``: MQTT on, to that broker."""
    host, _, port = broker.rpartition(":") if broker.count(":") == 1 else (broker, "", "")
    if port:
        if not port.isdigit() or not 0 < int(port) <= 65535:
            raise ConfigError("--mqtt", None, "must be HOST or HOST:PORT, the port 1 to 65535 (got {!r})".format(
                broker))
        mqtt.port = int(port)
    mqtt.host = host.strip("[]") or "localhost"
    mqtt.enabled = True
