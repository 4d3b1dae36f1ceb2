"""``python -m flask_move_server.drive`` (``flask-move-base``): the base controller alone.

For the mapping phase (gmapping needs ``/odom`` and tf, teleop needs motors)
without the HTTP server. Same config file and keys as the server (the
``drive`` and ``ros`` sections), the same ROS remappings and private params
(``~drive/backend``, ...). Exit status: 0 after SIGTERM/SIGINT, 1 when the
motors cannot be driven, 2 for a bad config, 3 when the ROS master was replaced.
"""

import argparse
import contextlib
import logging
import signal
import sys
import threading

from flask_move_server import config as config_mod
from flask_move_server.app import launching
from flask_move_server.core.errors import ConfigError, DriveError
from flask_move_server.drive.backends import NONE, motor_names

log = logging.getLogger("flask_move_server")


def parse_args(argv):
    parser = argparse.ArgumentParser(
        prog="flask-move-base",
        description="Run only the base controller: /cmd_vel to the motors, /odom and tf odom → base_link.",
    )
    parser.add_argument("--config", metavar="FILE", help="server config (YAML); its drive: and ros: sections apply")
    parser.add_argument("--motor-backend", choices=motor_names(), help="motor driver")
    parser.add_argument("--node-name", default="base_controller", help="ROS node name (default base_controller)")
    parser.add_argument("--log-level", default="INFO", choices=launching.LOG_LEVELS)
    return parser.parse_args(argv)


def load_config(args, ros_args):
    """The config file, then private params under roslaunch, then --motor-backend."""
    config = config_mod.load(args.config)
    node_name = launching.ros_node_name(ros_args)
    if node_name:
        config = launching.apply_private_params(config, node_name)
    if args.motor_backend:
        config.drive.backend = args.motor_backend
    if config.drive.backend == NONE:
        raise ConfigError(config.source, "drive.backend",
                          "is none: nothing to drive; choose {} (--motor-backend)".format(" or ".join(motor_names())))
    return config


def run(config, node_name, stopping):
    """Drive until ``stopping`` is set; returns the exit status."""
    from flask_move_server.drive import make_drive
    from flask_move_server.ros.node import RosNode

    status = {"code": launching.EXIT_OK}

    def fatal(reason):
        log.error("stopping: %s", reason)
        status["code"] = launching.EXIT_MASTER_REPLACED
        stopping.set()

    with contextlib.ExitStack() as stack:
        node = RosNode(node_name, config.ros.master_check_period, config.ros.exit_on_new_master, fatal)
        stack.callback(node.close)
        drive = make_drive(config.drive, node, config.ros.frames, source=config.source)
        stack.callback(drive.close)
        node.start()
        log.info("base controller (%s) waiting for the ROS master", config.drive.backend)
        stopping.wait()
    return status["code"]


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    ours, ros_args = launching.split_ros_args(argv)
    args = parse_args(ours)
    launching.setup_logging(args.log_level)
    stopping = threading.Event()
    for sig in (signal.SIGTERM, signal.SIGINT):
        signal.signal(sig, lambda signum, frame: stopping.set())
    try:
        config = load_config(args, ros_args)
        return run(config, args.node_name, stopping)
    except ConfigError as exc:
        return launching.refuse("flask-move-base", exc, launching.EXIT_CONFIG)
    except DriveError as exc:
        return launching.refuse("flask-move-base", "cannot drive the motors: {}".format(exc), launching.EXIT_FAILURE)


if __name__ == "__main__":
    sys.exit(main())
