"""Velocity commands from ``POST /teleop`` onto ``/cmd_vel``, with a deadman.

A command holds for ``deadman`` seconds: it is re-published at ``rate`` Hz
while it holds, and one zero Twist is published when it expires without a new
command, so the base stops even if its own watchdog is slower. A zero Twist
is ramped down by the base controller like any command, so the expiry also
calls the ``on_expire`` callbacks (the Robot: halt the motors at once).
"""

import logging
import threading
import time

from geometry_msgs.msg import Twist

from flask_move_server.core.errors import RosUnavailable
from flask_move_server.core.geometry import clamp
from flask_move_server.ros.convert import twist
from flask_move_server.ros.direct import direct_publisher

log = logging.getLogger(__name__)


class Teleop:
    """The teleop command in force and the thread that keeps it alive."""

    def __init__(self, config, node):
        self._config = config
        self._node = node
        self._cond = threading.Condition()
        self._linear = self._angular = 0.0
        self._by = "owner"
        self._deadline = None
        self._last_publish = 0.0
        self._pub = None
        self._closed = False
        self._thread = None
        self._expire_callbacks = []
        node.when_ready(self._setup)

    def on_expire(self, callback):
        """Call ``callback()`` when a command runs out without a new one (not on a zero command)."""
        self._expire_callbacks.append(callback)

    def _setup(self):
        # Written from the request's thread when the socket takes it at once (as goals are): rospy's
        # queued publisher handed every command to a writer thread first, 0.06 ms (bench_teleop).
        self._pub = direct_publisher(self._config.topic, Twist, 1)
        self._thread = threading.Thread(target=self._run, name="teleop", daemon=True)
        self._thread.start()

    def command(self, linear, angular, by="owner"):
        """Apply a velocity (clamped to the limits) for the deadman time; ``by``: who drives, ``owner``
        (``POST /teleop``, the joystick) or ``back_out`` (the robot itself, getting unstuck: recovery/)."""
        if self._pub is None or not self._node.connected:
            raise RosUnavailable(
                "ROS is not reachable at {}: cannot publish velocity commands.".format(self._node.master_uri)
            )
        linear, angular = clamp(linear, self._config.max_linear), clamp(angular, self._config.max_angular)
        with self._cond:
            self._linear, self._angular, self._by = linear, angular, by
            self._deadline = time.monotonic() + self._config.deadman
            self._publish(linear, angular)
            self._cond.notify_all()
        # Give up the GIL now that the Twist is on the wire: the base controller's subscriber (in this
        # process on the robot) applies it before this thread builds the HTTP answer (bench_teleop:
        # motors set 0.2 ms sooner, level with rosbridge_websocket).
        time.sleep(0)
        return {"linear": linear, "angular": angular, "hold": self._config.deadman}

    def stop(self):
        """End any command in force and publish one zero Twist."""
        with self._cond:
            self._deadline = None
            self._linear = self._angular = 0.0
            self._cond.notify_all()
        if self._pub is not None and self._node.connected and not self._closed:
            self._pub.publish(Twist())

    def end_command(self):
        """End a command in force with one zero Twist (as :meth:`stop`); with none in force, publish nothing.

        A goal ends teleop this way: a zero Twist on every goal would be one more message on
        the goal's way, competing with it for the GIL, to stop a base nobody drives.
        """
        with self._cond:
            in_force = self._deadline is not None
        if in_force:
            self.stop()

    def status(self):
        """The ``teleop`` part of ``/status``."""
        with self._cond:
            remaining = None if self._deadline is None else max(0.0, self._deadline - time.monotonic())
            return {
                "active": remaining is not None,
                "by": self._by if remaining is not None else None,
                "linear": self._linear,
                "angular": self._angular,
                "remaining": None if remaining is None else round(remaining, 3),
                "deadman": self._config.deadman,
                "max_linear": self._config.max_linear,  # the clamp: a page scales its joystick to these
                "max_angular": self._config.max_angular,
            }

    def close(self):
        """Stop the robot and the thread. Idempotent."""
        if self._closed:
            return
        self.stop()
        with self._cond:
            self._closed = True
            self._cond.notify_all()
        if self._thread is not None:
            self._thread.join(timeout=2)
        if self._pub is not None:
            self._pub.unregister()

    def _run(self):
        period = 1.0 / self._config.rate
        with self._cond:
            while not self._closed:
                if self._deadline is None:
                    self._cond.wait()
                    continue
                now = time.monotonic()
                if now >= self._deadline:
                    self._expire()
                    continue
                wake = self._last_publish + period
                if wake > self._deadline - period / 2:  # a re-publish this late could reach the base after the halt
                    wake = self._deadline
                if now >= wake:
                    self._publish(self._linear, self._angular)
                else:
                    self._cond.wait(wake - now)

    def _expire(self):
        """The deadman ran out (lock held, so a new command waits): halt, then one zero Twist."""
        self._deadline = None
        self._linear = self._angular = 0.0
        for callback in self._expire_callbacks:
            try:
                callback()
            except Exception:
                log.exception("teleop expiry callback %r failed", callback)
        self._pub.publish(Twist())

    def _publish(self, linear, angular):
        self._last_publish = time.monotonic()
        self._pub.publish(twist(linear, angular))
