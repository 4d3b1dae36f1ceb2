"""The process's rospy node: started in the background, watched, closed once.

``rospy.init_node`` blocks until a master answers, so it runs in a thread:
HTTP serves from the first second and ``/health`` says ``"ros": "waiting"``
until the node is registered. Parts that need the node (navigator, pose
tracker, teleop, base controller) register a callback with :meth:`when_ready`.
A part whose set-up callback raises is named in :attr:`failed_parts` and the
node's :attr:`health` is ``degraded``, not ``connected``: the rest of the robot
still works, but /health and /status must not promise what that part does.

The master is then watched. When it stops answering, the node is ``lost``
(``/health`` says so; ``on_lost`` callbacks stop the motors). When a *new*
master answers (its pid, or its ``/run_id``, changed) this node is not registered
with it and rospy cannot re-register, so ``on_fatal`` is called: the server
exits non-zero and systemd restarts it cleanly.

A node already registered under this node's name that still answers (another server on the
same master) is never replaced: rospy would shut *it* down, and with it the robot its owner is
driving. This node then stops at once (state ``name_in_use``, ``on_fatal``) saying so.
"""

import logging
import sys
import threading
import time

from flask_move_server.process import ast_guard
from flask_move_server.process.log_limits import ThrottleFilter
from flask_move_server.ros import master

log = logging.getLogger(__name__)

ACTIONLIB_STORM_LINES = ("already in the DONE state", "received DONE twice")
ast_guard.serialise_ast_parse()  # rospy's threads format tracebacks while an app may be parsing routes

WAITING, CONNECTED, LOST, NEW_MASTER, CLOSED = "waiting", "connected", "lost", "new_master", "closed"
NAME_IN_USE = "name_in_use"  # another live node has this node's name: this one never registers
DEGRADED = "degraded"  # connected, but a part's set-up failed (see RosNode.failed_parts)


class RosNode:
    """One rospy node per process, with its master watched from a thread."""

    def __init__(self, name="flask_move_server", check_period=1.0, exit_on_new_master=True, on_fatal=None):
        self.name = name
        self.check_period = check_period
        self.exit_on_new_master = exit_on_new_master
        self.on_fatal = on_fatal
        self.state = WAITING
        self._identity = None
        self._owns_rospy = False
        self._ready_callbacks = []
        self._failed_parts = []
        self._lost_callbacks = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = None
        self._watcher = None

    @property
    def master_uri(self):
        return master.master_uri()

    @property
    def connected(self):
        return self.state == CONNECTED

    @property
    def failed_parts(self):
        """``[{"part": name, "error": message}]`` for every part whose set-up raised."""
        with self._lock:
            return [dict(part) for part in self._failed_parts]

    @property
    def health(self):
        """The node's state as /health tells it: ``degraded`` when connected with a part not set up."""
        state = self.state
        if state == CONNECTED and self._failed_parts:
            return DEGRADED
        return state

    def when_ready(self, callback, part=None):
        """Run ``callback()`` once the node is registered (at once if it is and set up).

        ``part``: the name /status gives the part if its set-up fails (default: the class of
        a bound method's object, ``Teleop``, ``Navigator``...).
        """
        with self._lock:
            if self.state not in (WAITING, CLOSED):
                run_now = True
            else:
                self._ready_callbacks.append((callback, part))
                run_now = False
        if run_now:
            self._set_up(callback, part)

    def when_lost(self, callback):
        """Run ``callback()`` each time the master stops answering."""
        self._lost_callbacks.append(callback)

    def start(self):
        """Start connecting in the background; returns at once."""
        self._thread = threading.Thread(target=self._run, name="ros-node", daemon=True)
        self._thread.start()

    def wait_connected(self, timeout):
        """Block until connected or ``timeout``; True when connected."""
        deadline = time.monotonic() + timeout
        while not self.connected and time.monotonic() < deadline and not self._stop.is_set():
            self._stop.wait(0.05)
        return self.connected

    def close(self):
        """Stop watching and shut the rospy node down (if this object started it). Idempotent."""
        if self.state == CLOSED:
            return
        self.state = CLOSED
        self._stop.set()
        if self._owns_rospy:
            import rospy

            rospy.signal_shutdown("flask-move-server stopping")  # also ends rospy's retry loops
        for thread in (self._watcher, self._thread):
            if thread is not None and thread is not threading.current_thread():
                thread.join(timeout=2)

    # the background thread ---------------------------------------------------

    def _run(self):
        uri = self.master_uri
        log.info("waiting for the ROS master at %s", uri)
        while self._identity is None and not self._stop.is_set():
            self._identity = master.identity(self.name, timeout=1.0)
            if self._identity is None:
                self._stop.wait(0.5)
        if self._stop.is_set() or self._name_in_use():
            return
        self._init_rospy()
        # Watch from a thread of its own: a callback registering topics with a master that
        # died meanwhile blocks inside rospy, and the loss must still be noticed.
        self._watcher = threading.Thread(target=self._watch, name="ros-master-watch", daemon=True)
        self._watcher.start()
        self._run_ready_callbacks()
        log.info("connected to the ROS master at %s as %s", uri, self.name)

    def _run_ready_callbacks(self):
        """Set every part up, then say ``connected``: /health must not promise what is not ready."""
        while True:
            with self._lock:
                callbacks, self._ready_callbacks = self._ready_callbacks, []
                if not callbacks:
                    if self.state == WAITING:
                        self.state = CONNECTED
                    return
            for callback, part in callbacks:
                self._set_up(callback, part)

    def _set_up(self, callback, part):
        """Run one part's set-up; a failure is logged and recorded, never fatal to the node."""
        try:
            callback()
        except Exception as exc:
            name = part or _part_name(callback)
            log.exception("the ROS set-up of %s failed; /health says %r until the server restarts", name, DEGRADED)
            with self._lock:
                self._failed_parts.append({"part": name, "error": "{}: {}".format(type(exc).__name__, exc)})

    def _name_in_use(self):
        """True (and on_fatal called) when a live node already has the name this node would register."""
        import rospy

        if rospy.core.is_initialized():
            return False
        name = _resolved_node_name(self.name)
        other = master.live_node(name, name, timeout=1.0)
        if other is None:
            return False
        self.state = NAME_IN_USE
        message = (
            "another node runs as {} with the ROS master at {} (pid {}): a second server on the same master "
            "would shut it down and strand the robot it drives. Stop that one first (on the robot: sudo "
            "systemctl stop flask-move-server), or give this server its own ros.node_name or ROS_MASTER_URI"
            .format(name, self.master_uri, other[0])
        )
        log.error(message)
        if self.on_fatal is not None:
            self.on_fatal(message)
        return True

    def _init_rospy(self):
        import rospy

        if rospy.core.is_initialized():
            self.name = rospy.get_name()
            return
        rospy.init_node(self.name, disable_signals=True)
        rospy.on_shutdown(_end_registration_retries)
        # actionlib's errors about a goal already ended come in goal storms, one per goal: throttled
        logging.getLogger("rosout").addFilter(ThrottleFilter(ACTIONLIB_STORM_LINES))
        self.name = rospy.get_name()
        self._owns_rospy = True

    def _watch(self):
        while not self._stop.wait(self.check_period):
            identity = master.identity(self.name, timeout=max(1.0, self.check_period))
            if self._owns_rospy and _rospy_shut_down() and not self._stop.is_set():
                self._name_taken()
                return
            if identity is None:
                self._master_gone()
            elif not self._identity.same_master(identity):
                self._master_replaced()
                return
            else:
                self._identity = identity  # keeps a run id set since (roslaunch against our master)
                if self.state == LOST:
                    log.warning("the ROS master at %s answers again", self.master_uri)
                    self.state = CONNECTED

    def _master_gone(self):
        if self.state != CONNECTED:
            return
        self.state = LOST
        log.error("the ROS master at %s stopped answering; motors stopped, goals unavailable", self.master_uri)
        for callback in self._lost_callbacks:
            _call(callback)

    def _name_taken(self):
        """rospy shut this node down: another node registered with our name (a second server?)."""
        self.state = LOST
        for callback in self._lost_callbacks:
            _call(callback)
        message = (
            "another node registered as {} with the ROS master at {} (a second server on the same master?), "
            "so rospy shut this one down; give each server its own ros.node_name".format(self.name, self.master_uri)
        )
        log.error(message)
        if self.on_fatal is not None:
            self.on_fatal(message)

    def _master_replaced(self):
        self.state = NEW_MASTER
        for callback in self._lost_callbacks:
            _call(callback)
        message = (
            "a new ROS master answers at {}; a rospy node cannot register again, "
            "so the server must restart".format(self.master_uri)
        )
        log.error(message)
        if self.exit_on_new_master and self.on_fatal is not None:
            self.on_fatal(message)


def _call(callback):
    """Run a callback; a failure is logged, never fatal to the node."""
    try:
        callback()
    except Exception:
        log.exception("ROS callback %r failed", callback)


def _part_name(callback):
    """What a set-up callback sets up: its object's class (``Teleop``), else its own name."""
    owner = getattr(callback, "__self__", None)
    if owner is not None:
        return type(owner).__name__
    return getattr(callback, "__qualname__", repr(callback))


def _rospy_shut_down():
    import rospy

    return rospy.core.is_shutdown()


def _resolved_node_name(name):
    """The global name rospy.init_node(``name``) registers: ``__name:=`` and the namespace applied."""
    import rosgraph.names

    name = rosgraph.names.load_mappings(sys.argv).get("__name", name)
    if name.startswith("/"):
        return name
    return rosgraph.names.ns_join(rosgraph.names.get_ros_namespace(argv=sys.argv), name)


def _end_registration_retries():
    """rospy's first shutdown hook: raise its shutdown flag before rospy's own clean-up runs.

    A topic registered while the master is gone retries inside rospy, holding the topic manager's
    lock, until ``rospy.is_shutdown()``; rospy's clean-up (a pre-shutdown hook, run before it raises
    that flag) waits for the same lock, so the process never ended (rospy 1.15 to 1.17:
    ``registration.py`` ``reg_added`` against ``topics.py`` ``close_all``). Raised here, the retry
    ends within its 0.2 s sleep and the clean-up goes on; nothing after this publishes.
    """
    import rospy.core

    rospy.core._shutdown_flag = True
