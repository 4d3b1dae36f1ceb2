"""``flask-move-server``: read the config, build every part, serve, stop cleanly.

Wiring and lifecycle only (the command line and the config it makes are server_options.py).
Parts are started in order and registered on an ExitStack, so SIGTERM/SIGINT (or a fatal ROS
event) closes them in reverse.
A signal stops the robot first (cancel the goal, end teleop, motors at zero;
a waiting /goto answers 503), then lets waitress drain, then closes the rest:
stop accepting requests, cancel the goal, zero the velocity, stop the motors,
withdraw the mDNS records, shut the ROS node down. Exit status: 0 after a
signal, 2 for a bad config, 3 when the ROS master was replaced (systemd
restarts the server).
"""

import contextlib
import errno
import logging
import os
import signal
import sys
import time

from flask_move_server.app import server_options
from flask_move_server.app.launching import (
    EXIT_CONFIG,
    EXIT_FAILURE,
    EXIT_MASTER_REPLACED,
    EXIT_OK,
    refuse,
    setup_logging,
    split_ros_args,
)
from flask_move_server.app.parts import ServerParts, build_robot  # noqa: F401 (cli.build_robot: tests build robots)
from flask_move_server.core.errors import ConfigError, DriveError, WaypointFileError

log = logging.getLogger("flask_move_server")


class Server(ServerParts):
    """The running server: every part, closed once, in reverse order of start."""

    def __init__(self, config):
        self.config = config
        self.exit_code = EXIT_OK
        self.http = None
        self.robot = None
        self.modes = None
        self.runs = None
        self.explorer = None
        self.mqtt = None
        self.happenings = None
        self._simulation = None
        self.events = None
        self._stack = contextlib.ExitStack()

    def start(self):
        from flask_move_server.core.events import EventBus
        from flask_move_server.http.server import HttpServer
        from flask_move_server.waypoints.store import WaypointStore
        from flask_move_server.web import create_app

        stack = self._stack
        store = WaypointStore(self.config.waypoints.file, self.config.waypoints.lock_timeout)
        self.events = EventBus()
        stack.callback(self.events.close)  # closed last of all: streams end after the robot stopped
        robot = self._build_robot(stack, store)
        self._report(stack, robot)
        self.modes = self._build_modes(stack)
        maps = self._build_maps(stack, store)
        runs = self._build_runs(stack, robot, store)
        explorer = self.explorer = self._build_explorer(stack, robot)
        self._build_recovery(stack, robot, store)
        self._build_zones(stack, robot, store)
        self._build_docking(stack, robot, store)
        self.happenings = self._build_happenings(stack, robot)
        self._go_home_when_low(stack, robot, runs, self.happenings)
        app = create_app(self.config, robot, store, token=self.config.resolved_token(), events=self.events,
                         modes=self.modes, maps=maps, doctor=self._build_doctor(robot), runs=runs,
                         explorer=explorer)
        self.http = HttpServer(app, self.config.server)
        stack.callback(self.http.close)
        stack.callback(robot.stop)
        self.port = int(self.http.effective_port)
        log.info("serving the API on http://%s:%d (waypoints: %s, %d loaded)",
                 self.config.server.host, self.port, store.path, len(store.all()))
        self._advertise(stack)
        self.mqtt = self._build_mqtt(stack, app, store)
        self._node.start()
        self.modes.restore()  # in the background: the remembered mode's stack starts once ROS answers
        return self

    def serve(self):
        """Serve until SIGTERM/SIGINT (or :meth:`fatal`); returns the exit status."""
        from flask_move_server.app import systemd

        # Under systemd: READY=1 once /health answers, WATCHDOG=1 while it does, STOPPING=1 first on close.
        self._stack.callback(systemd.Supervisor(self.config.server.host, self.port).start().close)
        try:
            self.http.run()
        finally:
            self.close()
        return self.exit_code

    def on_signal(self, signum, frame):
        """SIGTERM/SIGINT: stop the robot first (motors at zero, a waiting /goto answers 503), then drain."""
        received = time.monotonic()
        log.info("received %s, stopping", signal.Signals(signum).name)
        try:
            if self.robot is not None:
                self.robot.shutdown()
                motors = self.robot.drive.status()
                log.info("robot stopped %.1f ms after the signal: goal canceled, teleop ended, motors left %s right %s",
                         (time.monotonic() - received) * 1000, motors.get("left"), motors.get("right"))
        finally:
            if self.events is not None:
                self.events.close()  # open /events streams end now, not after waitress's 5 s drain
            if self.http is not None:
                self.http.finish_streams()
            raise SystemExit(self.exit_code)

    def fatal(self, reason):
        """Called from any thread: stop the server with a non-zero exit status.

        3 (systemd restarts it) when the master was replaced; 1 when another server holds the
        node's name (restarting cannot help until it stops).
        """
        from flask_move_server.ros.node import NAME_IN_USE

        log.error("stopping: %s", reason)
        in_use = getattr(getattr(self, "_node", None), "state", None) == NAME_IN_USE
        self.exit_code = EXIT_FAILURE if in_use else EXIT_MASTER_REPLACED
        os.kill(os.getpid(), signal.SIGTERM)

    def close(self):
        """Close every part in reverse order of start. Idempotent.

        With the master gone, the ROS node goes first: a topic that was registering with it holds
        rospy's lock until rospy shuts down, and the parts' unregistering would wait on it for ever.
        """
        from flask_move_server.ros.node import LOST

        node = getattr(self, "_node", None)
        if node is not None and node.state == LOST:
            node.close()
        self._stack.close()




def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    ours, ros_args = split_ros_args(argv)
    args = server_options.parse_args(ours)
    setup_logging(args.log_level)
    try:
        config = server_options.load_config(args, ros_args)
    except ConfigError as exc:
        return _refuse(exc, EXIT_CONFIG)
    server = Server(config)
    signal.signal(signal.SIGTERM, server.on_signal)
    signal.signal(signal.SIGINT, server.on_signal)
    try:
        server.start()
    except (ConfigError, WaypointFileError) as exc:
        server.close()
        return _refuse(exc, EXIT_CONFIG)
    except DriveError as exc:
        server.close()
        return _refuse("cannot drive the motors: {}".format(exc), EXIT_FAILURE)
    except OSError as exc:
        server.close()
        return _refuse(_cannot_start(exc, config.server), EXIT_FAILURE)
    except SystemExit:
        server.close()
        return server.exit_code
    try:
        return server.serve()
    except SystemExit:
        return server.exit_code


def _cannot_start(exc, server_config):
    """Why the server could not start, and for a taken port, what to do."""
    if exc.errno == errno.EADDRINUSE:
        return ("cannot listen on {}:{}: the port is in use (another flask-move-server or make demo?); stop it, "
                "or pick another port with --port (make demo DEMO_PORT=5001)".format(server_config.host,
                                                                                  server_config.port))
    return "cannot start: {}".format(exc)


def _refuse(reason, status):
    return refuse("flask-move-server", reason, status)


if __name__ == "__main__":
    sys.exit(main())
