"""The base controller: ``/cmd_vel`` → motor backend, with a watchdog and odometry.

Three event sources, each on its own thread, sharing one lock:

- rospy's subscriber thread delivers ``/cmd_vel``; the first ramp step is
  applied at once, so a command reaches the motors within a millisecond;
- the *control* thread ramps towards the target at ``control_rate`` while the
  ramp is under way, and integrates and publishes odometry at ``odom_rate``;
- the *watchdog* thread, independent of ROS callbacks, sleeps until the last
  command's deadline and stops the motors at once (no ramp) when no command
  came for ``cmd_vel_timeout`` seconds. Losing the ROS master stops them too.

While the e-stop latch (:mod:`.estop`) is engaged every command is refused,
whoever sends it (teleop, move_base, a joystick node).

Idle threads block on a condition: no busy loop (Pi 4 CPU).
"""

import copy
import logging
import threading
import time

from flask_move_server.core.errors import DriveError
from flask_move_server.drive import messages
from flask_move_server.drive.motion import Motion
from flask_move_server.drive.odometry import ENCODERS, OPEN_LOOP, Odometry

log = logging.getLogger(__name__)


class BaseController:
    """Drives one motor backend from velocity commands and reports odometry."""

    def __init__(self, config, node, backend, frames, clock=time.monotonic, estop=None):
        self.config = config
        self.estop = estop
        self.node = node
        self.backend = backend
        self.frames = frames
        self._clock = clock
        self.motion = Motion.from_config(config, backend.closed_loop)
        self.odometry = Odometry(ENCODERS if backend.has_encoders else OPEN_LOOP)
        self._cond = threading.Condition()
        self._last_command = None
        self._last_step = self._last_odom = clock()
        self._ticks = None
        self._tripped = False
        self._fault = None
        self._ignored = 0
        self._held = 0
        self._awaiting_zero = False  # after an e-stop: a zero command or rearm() before any motion
        self._said_awaiting_zero = False
        self._closed = False
        self._ros = None
        self._threads = [
            threading.Thread(target=self._watchdog, name="drive-watchdog", daemon=True),
            threading.Thread(target=self._control, name="drive-control", daemon=True),
        ]
        for thread in self._threads:
            thread.start()
        node.when_ready(self._setup_ros)
        node.when_lost(self._master_lost)
        if estop is not None:
            estop.when_engaged(self._estop_engaged)

    # commands -------------------------------------------------------------------

    def command(self, linear, angular):
        """Drive at (linear m/s, angular rad/s), clamped; NaN/Inf are ignored. True when applied.

        Refused (False) while the e-stop is latched: checked under the lock, so a command
        racing an engage either lands before the e-stop's halt or not at all.
        """
        with self._cond:
            if self.estop is not None and self.estop.latched:
                self._held += 1
                return False
            if self._awaiting_zero and not self._rearmed_by(linear, angular):
                self._held += 1
                return False
            if self._closed or not self.motion.command(linear, angular):
                self._ignored += 1
                return False
            now = self._clock()
            self._last_command = now
            self._tripped = False
            self._step(now)
            self._cond.notify_all()
            return True

    def _rearmed_by(self, linear, angular):
        """Lock held, after an e-stop: a zero command re-arms (True); anything else is refused.

        A node still streaming ``/cmd_vel`` (a joystick held, a script) drove the robot the moment
        the e-stop was released; as IEC 60204-1 asks of a reset, releasing moves nothing, and motion
        needs a zero command (the stick let go) or a deliberate new command (:meth:`rearm`) first.
        """
        if linear == 0.0 and angular == 0.0:
            self._awaiting_zero = False
            log.info("a zero /cmd_vel after the e-stop: motion commands are accepted again")
            return True
        if not self._said_awaiting_zero:
            self._said_awaiting_zero = True
            log.warning("refused a /cmd_vel (linear %s, angular %s) after the e-stop: a zero command, or a new "
                        "goal or teleop from the API, comes first", linear, angular)
        return False

    def rearm(self):
        """A deliberate new command from the API (a goal, teleop): motion is accepted again after an e-stop."""
        with self._cond:
            self._awaiting_zero = False

    def _on_cmd_vel(self, msg):
        if not self.node.connected:
            return  # master lost: stay stopped until it answers again
        refused = (self.estop is not None and self.estop.latched) or self._awaiting_zero
        if not self.command(msg.linear.x, msg.angular.z) and not refused:
            log.warning("ignored a /cmd_vel that is not finite: linear %s, angular %s", msg.linear.x, msg.angular.z)

    def stop(self, reason=None):
        """Stop the motors now (not ramped)."""
        with self._cond:
            self._integrate(self._clock())
            self.motion.halt()
            if reason:
                self._tripped = True
                log.warning("motors stopped: %s", reason)
            self._apply()
            self._cond.notify_all()

    def _master_lost(self):
        self.stop("the ROS master stopped answering")

    def _estop_engaged(self, source):
        """The latch halts the motors here, first and directly: no ROS on the way."""
        with self._cond:
            self._awaiting_zero, self._said_awaiting_zero = True, False
        self.stop()

    # the shared arithmetic (called with the lock held) -----------------------------

    def _step(self, now):
        self._integrate(now)
        dt = min(now - self._last_step, 1.0 / self.config.control_rate)
        self._last_step = now
        previous = self.motion.commands
        self.motion.step(dt)
        if self.motion.commands != previous:
            self._apply()

    def _apply(self):
        try:
            self.backend.set(*self.motion.commands)
        except Exception as exc:  # a failing backend is reported in /status, never fatal to the threads
            self._fault = str(exc) if isinstance(exc, DriveError) else "{}: {}".format(type(exc).__name__, exc)
            log.error("motor backend %s failed: %s", self.backend.name, exc)
            self.motion.halt()

    def _integrate(self, now):
        """Open-loop odometry: the velocity in force since the last call, up to ``now``."""
        if self.odometry.source == OPEN_LOOP:
            self.odometry.advance(*self.motion.actual_velocity(), now - self._last_odom)
            self._last_odom = now

    # threads ------------------------------------------------------------------------

    def _watchdog(self):
        timeout = self.config.cmd_vel_timeout
        with self._cond:
            while not self._closed:
                moving = self.motion.target != (0.0, 0.0) or self.motion.commands != (0.0, 0.0)
                if not moving or self._last_command is None:
                    self._cond.wait()
                    continue
                remaining = self._last_command + timeout - self._clock()
                if remaining > 0:
                    self._cond.wait(remaining)
                    continue
                self._integrate(self._clock())
                self.motion.halt()
                self._tripped = True
                self._apply()
                log.warning("no /cmd_vel for %.2f s: motors stopped", timeout)

    def _control(self):
        control_period = 1.0 / self.config.control_rate
        odom_period = 1.0 / self.config.odom_rate
        next_odom = self._clock()
        while True:
            with self._cond:
                if self._closed:
                    return
                now = self._clock()
                if not self.motion.settled and now - self._last_step >= control_period:
                    self._step(now)
                if now < next_odom:
                    wake = next_odom if self.motion.settled else min(next_odom, self._last_step + control_period)
                    self._cond.wait(max(wake - now, 0.0))
                    continue
                next_odom += odom_period
                if next_odom < now:  # fell behind (a slow serial read): skip, do not burst
                    next_odom = now + odom_period
            self._odometry_tick()

    def _odometry_tick(self):
        ticks = self.backend.read_encoders() if self.backend.has_encoders else None
        with self._cond:
            now = self._clock()
            if self.odometry.source == ENCODERS:
                self._count_ticks(ticks, now)
            else:
                self._integrate(now)
            ros, reading = self._ros, copy.copy(self.odometry)
        if ros is not None and self.node.connected:
            ros.publish(reading)

    def _count_ticks(self, ticks, now):
        if ticks is None:
            self._ticks = None
            self.odometry.linear = self.odometry.angular = 0.0
            return
        if self._ticks is not None:
            per_metre = self.backend.ticks_per_metre
            left, right = ((t - p) / per_metre for t, p in zip(ticks, self._ticks))
            self.odometry.advance_wheels(left, right, self.motion.kinematics.effective_track, now - self._last_odom)
        self._ticks = ticks
        self._last_odom = now

    # ROS ------------------------------------------------------------------------------

    def _setup_ros(self):
        with self._cond:
            if self._closed:
                return
            self._ros = messages.OdometryPublisher(self.config, self.frames, self._on_cmd_vel)
        log.info("base controller: %s on %s, odometry on %s (%s)", self.backend.name, self.config.cmd_vel_topic,
                 self.config.odom_topic, self.odometry.source)

    # status and lifecycle -----------------------------------------------------------

    def status(self):
        """The ``motors`` part of ``/status``: backend, applied left/right, watchdog, odometry."""
        with self._cond:
            connected = bool(self.backend.connected)
            left, right = self.motion.commands if connected else (0.0, 0.0)
            age = None if self._last_command is None else round(self._clock() - self._last_command, 3)
            return {
                "backend": self.backend.name,
                "left": round(left, 4),
                "right": round(right, 4),
                "watchdog_tripped": self._tripped,
                "command_age": age,
                "cmd_vel_timeout": self.config.cmd_vel_timeout,
                "target": {"linear": self.motion.target[0], "angular": self.motion.target[1]},
                "connected": connected,
                "error": self._fault or self.backend.error,
                "ignored_commands": self._ignored,
                "estop_refused_commands": self._held,
                "awaiting_zero": self._awaiting_zero,
                "odom": self.odometry.as_dict(),
            }

    def close(self):
        """Stop the motors, end the threads, release the backend and ROS topics. Idempotent."""
        with self._cond:
            if self._closed:
                return
            self.motion.halt()
            self._apply()
            self._closed = True
            self._cond.notify_all()
            ros, self._ros = self._ros, None
        for thread in self._threads:
            if thread is not threading.current_thread():
                thread.join(timeout=5)
        self.backend.close()
        if ros is not None:
            ros.close()

