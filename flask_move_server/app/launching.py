"""What every entry point needs at launch: ROS arguments, node names, private params, logging, exit codes.

``flask-move-server`` (cli), ``flask-move-base`` (drive/__main__) and
``record-waypoints`` (recorder) all start the same way under roslaunch: split
the ``name:=value`` remappings roslaunch appends from their own options, find
the node's full name, read its private params from the master, and log to
stderr in a form journald understands. That plumbing lives here so no entry
point has to import another (cli only wires the server).
"""

import logging
import os
import sys
import time

from flask_move_server import config as config_mod
from flask_move_server.core.errors import ConfigError

log = logging.getLogger("flask_move_server")

EXIT_OK, EXIT_FAILURE, EXIT_CONFIG, EXIT_MASTER_REPLACED = 0, 1, 2, 3
LOG_LEVELS = ["DEBUG", "INFO", "WARNING", "ERROR"]

# How long to wait for the master's answer about private params. roslaunch sets them before it
# starts the node, so a master that does not answer is busy (a Pi booting), not absent.
PARAMS_WAIT = 30.0
_FIRST_TRY = 2.0


def split_ros_args(argv):
    """Separate ROS remapping arguments (``name:=value``, as roslaunch adds) from ours."""
    ours = [a for a in argv if ":=" not in a]
    ros = [a for a in argv if ":=" in a]
    return ours, ros


def ros_node_name(ros_args):
    """The node's full name (``/ns/name``) when roslaunch named it (``__name:=``), else None."""
    remaps = dict(a.split(":=", 1) for a in ros_args)
    name = remaps.get("__name")
    if not name:
        return None
    namespace = remaps.get("__ns") or os.environ.get("ROS_NAMESPACE", "/")
    return "/" + "/".join(p for p in (namespace.strip("/"), name) if p)


def apply_private_params(config, node_name, wait=PARAMS_WAIT):
    """Private params mirror the config file's sections (``~server/port``, ``~drive/backend``, ...).

    Waits up to ``wait`` seconds for the master to answer; ConfigError (exit 2) when it never
    does, because starting without the params roslaunch gave would serve the wrong settings.
    """
    params = read_private_params(node_name, wait)
    if not params:
        return config
    source = "ROS params of {}".format(node_name)
    config_file = params.pop("config", None)
    if config_file:
        config = config_mod.load(config_file)
    merged = config_mod.merge(config_mod.as_plain(config), params)
    result = config_mod.build(config_mod.Config, merged, source=source)
    result.source = source
    return result


def read_private_params(node_name, wait=PARAMS_WAIT):
    """The node's private params ({} when none are set), waiting up to ``wait`` s for the master."""
    from flask_move_server.ros import master

    deadline = time.monotonic() + wait
    params = master.private_params(node_name, timeout=max(0.1, min(_FIRST_TRY, wait)))
    if params is None:
        log.warning("the ROS master at %s does not answer yet; waiting up to %.0f s for the private params of %s",
                    master.master_uri(), wait, node_name)
    while params is None and time.monotonic() < deadline:
        time.sleep(min(0.5, max(0.0, deadline - time.monotonic())))
        params = master.private_params(node_name, timeout=max(0.5, deadline - time.monotonic()))
    if params is None:
        raise ConfigError("ROS params of {}".format(node_name), None,
                          "the ROS master at {} did not answer within {:.0f} s, so the private params roslaunch "
                          "set cannot be read; is roscore running there?".format(master.master_uri(), wait))
    return params


def setup_logging(level):
    """Log to stderr: syslog priority prefixes under journald, timestamps on a terminal."""
    handler = logging.StreamHandler(sys.stderr)
    if os.environ.get("JOURNAL_STREAM"):
        handler.setFormatter(JournalFormatter())
    else:
        handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    # Not on the root logger: rospy.init_node replaces the root logger's handlers. And not passed on
    # to them either (propagate): rospy's root handler writes and flushes every record to a rotating
    # ROS log file, on the request thread and while the goal waits for the GIL to be sent.
    for name in ("flask_move_server", "waitress"):
        logger = logging.getLogger(name)
        logger.handlers[:] = [handler]
        logger.setLevel(level)
        logger.propagate = False


class JournalFormatter(logging.Formatter):
    """``<priority>logger: message``: journald reads the sd-daemon(3) prefix as the record's level."""

    _PRIORITY = {"DEBUG": 7, "INFO": 6, "WARNING": 4, "ERROR": 3, "CRITICAL": 2}

    def format(self, record):
        return "<{}>{}: {}".format(self._PRIORITY.get(record.levelname, 6), record.name, super().format(record))


def refuse(prog, reason, status):
    """Say why ``prog`` cannot start, one line on stderr; returns ``status`` for ``sys.exit``."""
    print("{}: {}".format(prog, reason), file=sys.stderr)
    return status
