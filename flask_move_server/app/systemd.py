"""Living under systemd: sd_notify readiness and watchdog.

``flask-move-server.service`` is ``Type=notify`` with ``WatchdogSec=``. :class:`Supervisor`
tells systemd ``READY=1`` once the HTTP server answers ``/health`` (by then the motors are
initialised and stopped: the robot is built before the server serves), then sends
``WATCHDOG=1`` at half the watchdog interval, but only while a real request to our own
``/health`` succeeds: a hung HTTP loop stops the pings and systemd restarts the server.
``STOPPING=1`` is sent when the server begins to shut down.

The protocol is a datagram on the AF_UNIX socket named by ``$NOTIFY_SOCKET`` (sd_notify(3)),
spoken here with the standard library only. Without ``$NOTIFY_SOCKET`` (not under systemd)
everything here does nothing.

The motors' safe stop after the server exits (the units' ``ExecStopPost=``) is
``python -m flask_move_server.drive.safe_stop``, beside the L298N backend it stops;
``python -m flask_move_server.systemd safe-stop`` still runs it for units installed earlier.
"""

import http.client
import logging
import os
import socket
import sys
import threading

log = logging.getLogger(__name__)


class Notifier:
    """Sends sd_notify state lines to systemd; a no-op outside systemd."""

    def __init__(self, environ=None):
        environ = os.environ if environ is None else environ
        address = environ.get("NOTIFY_SOCKET") or None
        if address and address.startswith("@"):
            address = "\0" + address[1:]  # abstract namespace socket
        self.address = address
        self._socket = None
        self._lock = threading.Lock()

    @property
    def enabled(self):
        """True when systemd asked for notifications."""
        return self.address is not None

    def notify(self, *states):
        """Send ``states`` (``"READY=1"``, ...) in one datagram; False when it could not be sent."""
        if not self.enabled:
            return False
        message = "\n".join(states).encode("utf-8")
        with self._lock:
            try:
                if self._socket is None:
                    self._socket = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
                self._socket.sendto(message, self.address)
            except OSError as exc:
                log.warning("cannot notify systemd at %s: %s", self.address, exc)
                return False
        return True

    def close(self):
        """Close the socket. Idempotent."""
        with self._lock:
            if self._socket is not None:
                self._socket.close()
                self._socket = None


def watchdog_interval(environ=None):
    """The watchdog timeout systemd set for this process, in seconds, or None."""
    environ = os.environ if environ is None else environ
    pid = environ.get("WATCHDOG_PID")
    if pid and pid.strip() != str(os.getpid()):
        return None  # meant for another process (e.g. our parent shell)
    try:
        usec = int(environ.get("WATCHDOG_USEC", ""))
    except ValueError:
        return None
    return usec / 1e6 if usec > 0 else None


def http_answers(host, port, timeout):
    """True when ``GET /health`` on our own HTTP server answers 200 within ``timeout``."""
    host = {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}.get(host, host)
    conn = http.client.HTTPConnection(host, port, timeout=timeout)
    try:
        conn.request("GET", "/health")
        response = conn.getresponse()
        response.read()
        return response.status == 200
    except (OSError, http.client.HTTPException):
        return False
    finally:
        conn.close()


class Supervisor:
    """READY=1 when HTTP serves, WATCHDOG=1 while it keeps serving, STOPPING=1 on close."""

    def __init__(self, host, port, notifier=None, interval=None, check=None):
        self.notifier = notifier or Notifier()
        self.interval = watchdog_interval() if interval is None else interval
        self.check = check or (lambda timeout: http_answers(host, port, timeout))
        self.ready = False
        self._stop = threading.Event()
        self._thread = None
        self._closed = False

    def start(self):
        """Start watching in a thread (only under systemd); returns self."""
        if self.notifier.enabled:
            self._thread = threading.Thread(target=self._run, name="systemd-notify", daemon=True)
            self._thread.start()
        return self

    def _run(self):
        period = self.interval / 2.0 if self.interval else None
        timeout = min(2.0, period / 2.0) if period else 2.0
        while not self._stop.is_set() and not self.check(timeout):
            self._stop.wait(0.1)
        if self._stop.is_set():
            return
        self.ready = self.notifier.notify("READY=1", "STATUS=serving HTTP")
        log.info("told systemd the server is ready%s",
                 " (watchdog every {:.1f} s)".format(period) if period else "")
        while period and not self._stop.wait(period):
            if self.check(timeout):
                self.notifier.notify("WATCHDOG=1")
            else:
                log.warning("own /health did not answer within %.1f s: withholding the watchdog ping", timeout)

    def close(self):
        """Stop pinging and tell systemd we are stopping. Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self._thread is not None:
            self._thread.join(5)
            self.notifier.notify("STOPPING=1", "STATUS=stopping")
        self.notifier.close()


def main(argv=None):
    """``python -m flask_move_server.systemd safe-stop [--config FILE]``: units installed before
    the command moved to ``flask_move_server.drive.safe_stop`` still run this one."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] != ["safe-stop"]:
        print("usage: python -m flask_move_server.systemd safe-stop [--config FILE]", file=sys.stderr)
        return 2
    from flask_move_server.drive import safe_stop

    return safe_stop.main(argv[1:], prog="python -m flask_move_server.systemd safe-stop")


if __name__ == "__main__":
    sys.exit(main())
