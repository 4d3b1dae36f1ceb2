"""``robotctl drive``: keyboard teleop in a terminal.

Terminals report key presses, not releases: a held key arrives as the
keyboard's auto-repeat (a first repeat after ~250-600 ms, then ~30 per
second). So a key counts as held until ``release`` seconds pass without it;
while held, ``POST /teleop`` goes out at a steady ``rate`` (faster than the
server's deadman), and on release, space, ``q``, Ctrl-C, a closed terminal or
SIGTERM the robot gets ``POST /stop``.
"""

import contextlib
import os
import select
import signal
import termios
import time
import tty

from flask_move_server.core.errors import ClientError
from flask_move_server.robotctl.api import ExitStatus
from flask_move_server.robotctl.robot_clock import RobotClock

# key -> (forward, turn) as fractions of the speeds; left turn is positive (REP-103).
MOTION = {
    "w": (1, 0), "s": (-1, 0), "a": (0, 1), "d": (0, -1),
    "up": (1, 0), "down": (-1, 0), "left": (0, 1), "right": (0, -1),
}
_ARROWS = {"\x1b[A": "up", "\x1b[B": "down", "\x1b[C": "right", "\x1b[D": "left",
           "\x1bOA": "up", "\x1bOB": "down", "\x1bOC": "right", "\x1bOD": "left"}
LATE_AFTER = 1.0  # s: a command the robot reads later than this is refused (as the phone page's joystick)
HELP = "drive: arrows or WASD move, space stops, + / - change speed, q quits"


def parse_keys(text):
    """The key names in ``text``, as typed in a cbreak terminal (arrows are escape sequences)."""
    keys, i = [], 0
    while i < len(text):
        seq = text[i:i + 3]
        if seq in _ARROWS:
            keys.append(_ARROWS[seq])
            i += 3
            continue
        ch = text[i]
        keys.append({" ": "space", "\x03": "quit", "\x04": "quit", "\x1b": "escape"}.get(ch, ch.lower()))
        i += 1
    return keys


class _Hangup(Exception):
    """The terminal closed (SIGHUP) or the process was asked to stop (SIGTERM)."""


class KeyboardDriver:
    """Turns key presses into /teleop calls at a steady rate, and stops the robot."""

    def __init__(self, client, linear=0.2, angular=0.8, rate=5.0, release=0.7):
        self.client = client
        self.clock = RobotClock(client)  # each command is refused by the robot if it arrives late
        self.linear, self.angular = linear, angular
        self.period = 1.0 / rate
        self.release = release
        self.command = (0.0, 0.0)
        self._last_key = 0.0
        self._last_send = 0.0

    def run(self, stdin, stdout):
        """Drive until q / Ctrl-C / the terminal closes; the exit status."""
        if not stdin.isatty():
            raise ClientError("drive needs a terminal: run it in an interactive shell "
                              "(for scripts use 'robotctl teleop LIN ANG').", ExitStatus.USAGE)
        fd = stdin.fileno()
        self._out = stdout
        self.clock.sync()
        try:
            with _cbreak(fd), _signals_raise_hangup():
                self._show(HELP + "\r\n")  # once keys are read one by one: typing may start now
                self._loop(fd)
        except (KeyboardInterrupt, _Hangup):
            pass
        finally:
            self._stop_robot()
        self._show("\r\nstopped.\r\n")
        return ExitStatus.OK

    def _loop(self, fd):
        while True:
            ready, _, _ = select.select([fd], [], [], self._wait_time())
            now = time.monotonic()
            if ready:
                try:
                    data = os.read(fd, 64)
                except OSError:  # EIO: the terminal is gone
                    return
                if not data:  # end of input: the terminal is gone
                    return
                for key in parse_keys(data.decode("utf-8", "replace")):
                    if self._on_key(key, now) == "quit":
                        return
            self._tick(time.monotonic())

    def _on_key(self, key, now):
        if key in ("q", "quit"):
            return "quit"
        if key == "space":
            self._set((0.0, 0.0), now, stop=True)
        elif key in ("+", "=", "-"):
            factor = 1.25 if key != "-" else 0.8
            self.linear, self.angular = self.linear * factor, self.angular * factor
            self._show_command()
        elif key in MOTION:
            forward, turn = MOTION[key]
            self._last_key = now
            self._set((forward * self.linear, turn * self.angular), now)
        return None

    def _set(self, command, now, stop=False):
        changed = command != self.command
        self.command = command
        if stop or command == (0.0, 0.0):
            if changed or stop:
                self._stop_robot()
        elif changed:
            self._send(now)
        self._show_command()

    def _tick(self, now):
        if self.command == (0.0, 0.0):
            return
        if now - self._last_key >= self.release:  # key released
            self._set((0.0, 0.0), now, stop=True)
        elif now - self._last_send >= self.period:
            self._send(now)

    def _wait_time(self):
        if self.command == (0.0, 0.0):
            return None
        now = time.monotonic()
        return max(0.0, min(self._last_send + self.period, self._last_key + self.release) - now)

    def _send(self, now):
        self._last_send = now
        linear, angular = self.command
        body = dict({"linear": linear, "angular": angular}, **self.clock.deadline(LATE_AFTER))
        try:
            self.client.post("/teleop", body)
        except ClientError as exc:
            if (getattr(exc, "body", None) or {}).get("error") != "command_late":
                raise
            self._show("\r\033[Klate: the link to the robot stalled, so it dropped that command\r\n")

    def _stop_robot(self):
        self.command = (0.0, 0.0)
        with contextlib.suppress(ClientError):
            self.client.post("/stop")

    def _show_command(self):
        linear, angular = self.command
        self._show("\r\033[K{:+.2f} m/s  {:+.2f} rad/s   (speeds {:.2f} m/s, {:.2f} rad/s)".format(
            linear, angular, self.linear, self.angular))

    def _show(self, text):
        # Straight to the file descriptor: text left in Python's buffer when the terminal has
        # closed would fail again at exit and turn the exit status into 120.
        with contextlib.suppress(OSError, ValueError):
            self._out.flush()
            os.write(self._out.fileno(), text.encode("utf-8", "replace"))


@contextlib.contextmanager
def _cbreak(fd):
    """Keys arrive one by one, unechoed; the terminal is restored whatever happens."""
    saved = termios.tcgetattr(fd)
    tty.setcbreak(fd)
    try:
        yield
    finally:
        with contextlib.suppress(termios.error):
            termios.tcsetattr(fd, termios.TCSADRAIN, saved)


@contextlib.contextmanager
def _signals_raise_hangup():
    def _raise(signum, frame):
        raise _Hangup()

    previous = {sig: signal.signal(sig, _raise) for sig in (signal.SIGHUP, signal.SIGTERM)}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)

