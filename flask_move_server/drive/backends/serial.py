"""Backend ``serial``: a microcontroller speaking the ros_arduino_bridge protocol.

Existing ROSArduinoBridge firmware works unchanged. Commands are one line
each, ended by CR, answered by one line:

- ``m L R``: target speed of each side in encoder ticks per PID frame
  (``pid_rate`` frames a second), held by the firmware's PID → ``OK``;
- ``e``: cumulative encoder counts → ``"<left> <right>"``;
- ``r``: reset the encoder counts → ``OK``.

The firmware stops the motors by itself when no ``m`` came for 2 s, so the
command in force is repeated every ``keepalive`` seconds. The port is any
pyserial URL (``/dev/ttyACM0``, ``socket://host:port``, ``loop://``). An
unplugged cable means the motors are considered stopped (``connected`` is
False, ``/status`` says so) and the port is reopened every
``reconnect_period`` seconds until it answers again; encoder counts stay
continuous across the reconnect.
"""

import logging
import threading
import time

from flask_move_server.drive.backends import MotorBackend, register
from flask_move_server.drive.odometry import ticks_per_metre

log = logging.getLogger(__name__)


@register("serial")
class SerialBackend(MotorBackend):
    """Closed-loop motors behind a microcontroller on a serial port."""

    closed_loop = True
    has_encoders = True

    def __init__(self, config, source="(config)", clock=time.monotonic):
        import serial  # pyserial: imported when this backend is chosen

        self.serial = serial
        self._port_errors = _port_errors(serial)
        self.cfg = config.serial
        self.url = self.cfg.port
        self.ticks_per_metre = ticks_per_metre(self.cfg.ticks_per_rev, config.wheel_radius)
        self.ticks_per_frame = config.max_wheel_speed * self.ticks_per_metre / self.cfg.pid_rate
        self._clock = clock
        self._lock = threading.Lock()
        self._port = None
        self._command = (0, 0)
        self._sent_at = None
        self._next_attempt = 0.0
        self._base = [0, 0]  # counts carried over from before a reconnect
        self._last = [0, 0]
        self._closed = False
        self.error = None
        self._reconnect()

    @property
    def connected(self):
        return self._port is not None

    def set(self, left, right):
        """Target speeds as fractions of ``max_wheel_speed`` (-1..1), sent as ticks per frame."""
        command = (int(round(left * self.ticks_per_frame)), int(round(right * self.ticks_per_frame)))
        with self._lock:
            self._command = command
            if self._port is not None:
                self._send_motors()

    def read_encoders(self):
        """Cumulative (left, right) ticks, or None while unplugged. Also keeps the link alive."""
        if self._port is None:
            self._reconnect()
        with self._lock:
            if self._port is None:
                return None
            if self._sent_at is None or self._clock() - self._sent_at >= self.cfg.keepalive:
                self._send_motors()
            reply = self._transaction("e") if self._port is not None else None
            counts = _parse_counts(reply)
            if counts is None:
                return None
            self._last = [self._base[0] + counts[0], self._base[1] + counts[1]]
            return tuple(self._last)

    def close(self):
        """Stop the motors (``m 0 0``) and close the port. Idempotent."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._command = (0, 0)
            if self._port is not None:
                self._send_motors()
                self._drop(None)

    # the conversation ---------------------------------------------------------

    def _send_motors(self):
        self._transaction("m {} {}".format(*self._command))
        self._sent_at = self._clock()

    def _transaction(self, line):
        """One command and its reply line (None on a timeout); drops the port on failure."""
        port = self._port
        try:
            port.reset_input_buffer()
            port.write((line + "\r").encode("ascii"))
            reply = port.read_until(b"\n")
        except self._port_errors as exc:
            self._drop(exc)
            return None
        if not reply.endswith(b"\n"):
            log.warning("no answer to %r from the motor controller at %s", line, self.url)
            return None
        return reply.decode("ascii", "replace").strip()

    def _drop(self, exc):
        if exc is not None:
            self.error = "motor controller at {} lost: {}".format(self.url, exc)
            log.error("%s; motors considered stopped, reconnecting", self.error)
        port, self._port = self._port, None
        self._base = list(self._last)
        self._next_attempt = self._clock() + self.cfg.reconnect_period
        try:
            port.close()
        except Exception:
            pass

    def _reconnect(self):
        if self._closed or self._clock() < self._next_attempt:
            return
        self._next_attempt = self._clock() + self.cfg.reconnect_period
        try:
            port = self.serial.serial_for_url(
                self.url, baudrate=self.cfg.baudrate, timeout=self.cfg.timeout, write_timeout=self.cfg.timeout)
        except self._port_errors + (ValueError,) as exc:
            self.error = "cannot open the motor controller at {}: {}".format(self.url, exc)
            return
        if self.cfg.open_delay:
            time.sleep(self.cfg.open_delay)  # an Arduino reboots when its port opens
        with self._lock:
            self._port = port
            if self._transaction("r") is None and self._port is None:
                return
            self.error = None
            self._send_motors()
        log.info("motor controller at %s connected", self.url)


def _port_errors(serial):
    """What a vanished port raises: pyserial's error, OSError, and termios.error (not an OSError)."""
    errors = (serial.SerialException, OSError)
    try:
        import termios
    except ImportError:  # Windows
        return errors
    return errors + (termios.error,)


def _parse_counts(reply):
    if reply is None:
        return None
    parts = reply.split()
    try:
        return int(parts[0]), int(parts[1])
    except (IndexError, ValueError):
        log.warning("unexpected encoder reply %r", reply)
        return None

