"""A stand-in of the ROSArduinoBridge firmware on the far side of a pty pair.

The backend opens ``link`` (a symlink to the pty's slave side, like
``/dev/ttyACM0``) with pyserial; this object answers on the master side with
the firmware's protocol: ``m L R`` → ``OK``, ``e`` → ``"<left> <right>"``,
``r`` → ``OK``, ``b`` → the baud rate, anything else → ``Invalid Command``,
each reply ended by CR LF (``Serial.println``). Encoder counts are scripted by
the test (``encoders``). ``unplug()`` closes the pty (the backend's next read
or write fails, as with a pulled USB cable) and ``plug()`` brings it back at
the same path, with the counts reset as after a reboot.
"""

import os
import select
import threading
import tty


class FirmwareStandIn:
    """Speaks ros_arduino_bridge over a pty; records the commands it got."""

    def __init__(self, link):
        self.link = str(link)
        self.commands = []  # every command line received, in order
        self.motors = (0, 0)  # the last ``m`` targets, ticks per frame
        self.encoders = [0, 0]  # what ``e`` answers; tests script these
        self.silent = False  # True: read commands but never answer
        self._lock = threading.Lock()
        self._master = self._slave = None
        self._thread = None
        self._stop = threading.Event()
        self.plug()

    def plug(self):
        """Create the pty and the link to it; start answering."""
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        if os.path.lexists(self.link):
            os.unlink(self.link)
        os.symlink(os.ttyname(self._slave), self.link)
        with self._lock:
            self.encoders = [0, 0]
            self.motors = (0, 0)
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, name="firmware-standin", daemon=True)
        self._thread.start()

    def unplug(self):
        """Pull the cable: the pty and the link disappear."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5)
        for fd in (self._master, self._slave):
            if fd is not None:
                os.close(fd)
        self._master = self._slave = None
        if os.path.lexists(self.link):
            os.unlink(self.link)

    def close(self):
        """Stop answering and remove the pty. Idempotent."""
        if self._master is not None:
            self.unplug()

    def motor_commands(self):
        """The ``m`` commands received, as (left, right) tuples."""
        with self._lock:
            lines = list(self.commands)
        return [tuple(int(v) for v in line.split()[1:3]) for line in lines if line.startswith("m ")]

    def _serve(self):
        buffer = b""
        while not self._stop.is_set():
            ready, _, _ = select.select([self._master], [], [], 0.05)
            if not ready:
                continue
            try:
                data = os.read(self._master, 256)
            except OSError:
                continue  # the backend has not opened its side yet
            buffer += data
            while b"\r" in buffer:
                line, buffer = buffer.split(b"\r", 1)
                reply = self._answer(line.decode("ascii").strip())
                if reply is not None and not self.silent:
                    os.write(self._master, (reply + "\r\n").encode("ascii"))

    def _answer(self, line):
        if not line:
            return None
        with self._lock:
            self.commands.append(line)
            parts = line.split()
            if parts[0] == "m" and len(parts) == 3:
                self.motors = (int(parts[1]), int(parts[2]))
                return "OK"
            if parts[0] == "e":
                return "{} {}".format(*self.encoders)
            if parts[0] == "r":
                self.encoders = [0, 0]
                return "OK"
            if parts[0] == "b":
                return "57600"
        return "Invalid Command"
