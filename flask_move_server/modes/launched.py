"""The robot's navigation stack as a supervised ``roslaunch`` child: the ``roslaunch`` stack backend.

``mapping`` runs ``roslaunch <modes.mapping_launch> server:=false``; ``navigation`` runs
``roslaunch <modes.navigation_launch> server:=false [map:=<yaml>]`` (no map: the launch file's
default). The launch files must declare the args ``server`` (and ``map`` for navigation).
roslaunch runs in the server's environment (ROS_PACKAGE_PATH, ROS_HOME, ``$(optenv ...)``).

Before roslaunch starts, its launch file is parsed in this process: a node whose package or
executable is missing fails at once with the apt command that installs it, and the nodes that
respawn are known (roslaunch restarts them; their death is not the stack's), and so is whether
it runs move_base. A mode is ready when its parts answer, asked of the ROS master (no rospy node
needed): when a process of ours publishes the map topic and, if the stack runs move_base (always
in navigation; in mapping unless its launch file leaves move_base out), ``<navigation.action>/status``.
A registration left by a killed node never counts: its pid must be one of our stack's.
"""

import logging
import os
import shutil
import threading
import time
from concurrent.futures import ThreadPoolExecutor

from flask_move_server.core.errors import StackFailed
from flask_move_server.modes import child, readiness
from flask_move_server.modes.targets import MODES
from flask_move_server.process import children

log = logging.getLogger(__name__)


def _sim_default_map():
    from flask_move_server.sim.demo_map import default_map

    return default_map()

class LaunchedStack:
    """Runs one mode's launch file at a time; ``start`` blocks until ready, ``stop`` until all is gone."""

    def __init__(self, modes, map_topic="map", action="move_base", master_uri=None, world=None):
        """``world``: the simulated world's map (``--sim``): its lidar is the world's, and it is the default map."""
        self.modes = modes
        self.world = world
        self.map_topic = readiness.global_name(map_topic)
        self.status_topic = readiness.global_name(action.rstrip("/") + "/status")
        self.master_uri = master_uri
        self._lock = threading.Lock()
        self._proc = None
        # Does mapping's launch file run move_base? The shipped one does (move_base:=false leaves it
        # out); each start reads it from the launch file. Navigation always runs move_base.
        self._mapping_goals = True
        self._stopping = False
        self._closed = False
        # roslaunch is started from this one thread, alive until close(): the parent-death signal
        # (children.die_with_parent) fires when the thread that started a child ends, not the process,
        # and a mode switch's thread ends as soon as the stack runs.
        self._spawner = ThreadPoolExecutor(max_workers=1, thread_name_prefix="stack-spawner")

    @classmethod
    def from_config(cls, config):
        """The backend for a server :class:`~flask_move_server.config.Config`."""
        world = (config.sim.map or _sim_default_map()) if config.sim.enabled else None
        return cls(config.modes, config.maps.topic, config.navigation.action, world=world)

    def start(self, mode, map_yaml=None, on_exit=None):
        """Start ``mode``'s stack and block until it is ready; StackFailed says what went wrong.

        Whatever ran before is stopped first; ``idle`` only stops it.

        ``on_exit(message)`` is called once, from a watcher thread, if the stack dies by itself later.
        """
        if mode not in MODES:
            raise ValueError("unknown mode {!r}".format(mode))
        self.stop()
        self._sweep_orphans()
        if mode == "idle":  # no stack at all
            return
        with self._lock:
            if self._closed:
                raise StackFailed("the server is shutting down")
            self._stopping = False
        readiness.check_master(self.master_uri)
        command = self.command(mode, map_yaml)
        launch = readiness.check_launch(command[1:])
        respawning = launch.respawning
        if mode == "mapping":
            with self._lock:
                self._mapping_goals = launch.runs_move_base
        proc = child.StackProcess(command)
        try:
            self._spawner.submit(proc.start).result()
        except OSError as exc:
            raise StackFailed("cannot run roslaunch ({}): is ROS installed?".format(exc.strerror))
        except RuntimeError:  # close() shut the spawner down while this start was on its way
            raise StackFailed("the server is shutting down")
        with self._lock:
            closed, self._proc = self._closed, proc
        if closed:  # close() came while roslaunch was starting
            self.stop()
            raise StackFailed("the server is shutting down")
        self._wait_ready(proc, mode, respawning)
        threading.Thread(target=self._watch, args=(proc, respawning, on_exit), name="stack-watch",
                         daemon=True).start()

    def serves_goals(self, mode):
        """Whether ``mode``'s stack runs move_base: navigation always; mapping when its launch file does
        (the shipped mapping.launch, unless a launch file of yours includes it with move_base:=false).
        The mode manager waits for goals to reach it before "running", and admits goals by it."""
        if mode == "mapping":
            with self._lock:
                return self._mapping_goals
        return mode == "navigation"

    def command(self, mode, map_yaml=None):
        """The roslaunch command line of ``mode``."""
        launch = self.modes.mapping_launch if mode == "mapping" else self.modes.navigation_launch
        options = ["--skip-log-check", "--no-summary", "--disable-title",  # no du of ROS_HOME, no param dump
                   "--sigint-timeout={:g}".format(self.modes.stop_timeout), "--sigterm-timeout=2"]
        argv = [shutil.which("roslaunch") or "roslaunch"] + options + launch.split() + ["server:=false"]
        if self.world is not None:
            argv.append("lidar:=false")  # the simulated world publishes /scan and the laser's tf
        map_yaml = map_yaml or self.world
        if mode == "navigation" and map_yaml:
            argv.append("map:={}".format(os.path.abspath(map_yaml)))
        return argv

    def _wait_ready(self, proc, mode, respawning):
        wanted = [self.map_topic] + ([self.status_topic] if self.serves_goals(mode) else [])
        deadline = time.monotonic() + self.modes.start_timeout
        missing = wanted
        while True:
            with self._lock:
                if self._proc is not proc:
                    raise StackFailed("the {} stack was stopped before it was ready".format(mode))
            failure = self._failure(proc, respawning)
            if failure is None:
                missing = readiness.missing(wanted, proc.pids(), self.master_uri)
                if not missing:
                    log.info("the %s stack is ready (%s)", mode, ", ".join(wanted))
                    return
                if time.monotonic() > deadline:
                    failure = "the {} stack started, but after {:g} s nothing of it publishes {}".format(
                        mode, self.modes.start_timeout, " or ".join(missing))
            if failure is not None:
                self.stop()
                raise StackFailed(failure)
            with proc.changed:
                proc.changed.wait(0.2)

    def _failure(self, proc, respawning):
        """Why the stack is broken now (a sentence a user can act on), or None."""
        with proc.changed:
            events = [list(e) for e in proc.events]
        for event in events:
            if event[0] == "cannot_launch":
                return readiness.cannot_launch_message(*event[1:])
            if event[1] not in respawning:
                return died_message(*event[1:])
        code = proc.exit_code()
        if code is not None:
            return "roslaunch ended (status {}): {}".format(code, " / ".join(proc.last_lines(4)) or "no output")
        return None

    def _watch(self, proc, respawning, on_exit):
        """After start: report the first death of a part (or of roslaunch) once, unless we stopped it."""
        failure = None
        while failure is None:
            with proc.changed:
                proc.changed.wait(0.5)
            with self._lock:
                if self._stopping or self._proc is not proc:
                    return
            failure = self._failure(proc, respawning)
        log.error("the navigation stack failed: %s", failure)
        if on_exit is not None:
            on_exit(failure)

    def stop(self):
        """Stop the running stack, if any; blocks until every process of it is gone. Idempotent."""
        with self._lock:
            proc, self._proc = self._proc, None
            self._stopping = True
        if proc is not None:
            with proc.changed:
                proc.changed.notify_all()  # the watcher sees _stopping at once
            proc.stop(self.modes.stop_timeout)
            log.info("the navigation stack stopped")

    def close(self):
        """Stop and refuse further starts. Idempotent."""
        with self._lock:
            self._closed = True
        self.stop()
        self._spawner.shutdown(wait=True)  # after stop: the spawner's end signals no child of ours left

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    @property
    def running(self):
        """True while a stack started here is up (it may be dying: see ``on_exit``)."""
        with self._lock:
            return self._proc is not None and self._proc.exit_code() is None

    @staticmethod
    def _sweep_orphans():
        """Stop stacks left by a server that was killed before it could (PDEATHSIG's backup)."""
        leftovers = children.orphans()
        if leftovers:
            log.warning("stopping navigation stack processes left by a server that died: %s", sorted(leftovers))
            child.stop_tree(lambda: set(children.orphans()), 2.0)


def died_message(node, code, log_file=None, last_line=None):
    """One sentence for a node of the stack that ended, with what it said last."""
    if code is not None and code < 0:
        how = "was killed (signal {})".format(-code)
    elif code:
        how = "exited with status {}".format(code)
    else:
        how = "ended"
    said = " ({})".format(last_line) if last_line and code and code > 0 else ""  # a killed node said nothing
    where = "; its log: {}".format(log_file) if log_file else ""
    return "the navigation stack's {} node {}{}{}".format(node, how, said, where)
