"""sd_notify through a real AF_UNIX datagram socket, as systemd's notify socket works.

The server process (started like systemd starts it, with $NOTIFY_SOCKET and $WATCHDOG_USEC)
must say READY=1 only when HTTP answers, ping WATCHDOG=1 while it serves, and STOPPING=1 on
SIGTERM. In-process, an HTTP server whose requests hang gets no pings until it answers again.
The old ``systemd safe-stop`` command still runs the safe stop (tests/test_drive_safe_stop.py).
"""

import re
import signal
import socket
import time

import pytest
import requests

from flask_move_server.app import systemd
from tests.conftest import run_cli, stop_process, wait_for


@pytest.fixture
def notify_socket(tmp_path):
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
    path = str(tmp_path / "notify")
    sock.bind(path)
    sock.settimeout(0.2)
    yield path, sock
    sock.close()


def receive(sock, want, timeout=30.0):
    """Datagrams until one contains ``want``; returns them all (each a list of lines)."""
    got = []
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            got.append(sock.recv(4096).decode().split("\n"))
        except socket.timeout:
            continue
        if want in got[-1]:
            return got
    raise AssertionError("no {} within {}s; got {}".format(want, timeout, got))


def test_server_notifies_ready_watchdog_and_stopping(notify_socket, ros_master, tmp_path):
    path, sock = notify_socket
    proc = run_cli("--host", "127.0.0.1", "--port", "0", "--no-mdns", "--motor-backend", "none",
                   "--waypoints", str(tmp_path / "waypoints.yaml"),  # its mode.json beside it, not in the checkout
                   env={"NOTIFY_SOCKET": path, "WATCHDOG_USEC": "1000000"})
    try:
        before_ready = receive(sock, "READY=1")
        assert all("WATCHDOG=1" not in m for m in before_ready)
        port = _port_from_log(proc)
        # READY means serving: the very next request is answered.
        assert requests.get("http://127.0.0.1:{}/health".format(port), timeout=5).status_code == 200
        receive(sock, "WATCHDOG=1")
        receive(sock, "WATCHDOG=1")  # keeps pinging (every 0.5 s for a 1 s watchdog)
        proc.send_signal(signal.SIGTERM)
        receive(sock, "STOPPING=1")
        assert proc.wait(30) == 0
    finally:
        stop_process(proc)


def _port_from_log(proc):
    lines = []

    def port():
        lines.append(proc.stderr.readline())
        match = re.search(r"serving the API on http://[^:]+:(\d+)", lines[-1])
        return match and int(match.group(1))

    return wait_for(port, timeout=30, message="the server's port in its log")


class _HealthServer:
    """A real HTTP server on a free port whose /health can be made to hang, like a stuck loop."""

    def __init__(self):
        import http.server
        import threading

        self.hang = threading.Event()
        self.release = threading.Event()
        outer = self

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self):  # noqa: N802 (http.server's name)
                if outer.hang.is_set():
                    outer.release.wait(10)
                self.send_response(200)
                self.end_headers()
                self.wfile.write(b'{"status": "ok"}')

            def log_message(self, *args):
                pass

        self.httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.httpd.daemon_threads = True
        self.port = self.httpd.server_address[1]
        self.thread = threading.Thread(target=self.httpd.serve_forever, name="test-health", daemon=True)
        self.thread.start()

    def close(self):
        self.release.set()
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join(5)


def test_watchdog_pings_stop_while_http_hangs_and_resume_after(notify_socket):
    path, sock = notify_socket
    http = _HealthServer()
    supervisor = systemd.Supervisor("127.0.0.1", http.port, systemd.Notifier({"NOTIFY_SOCKET": path}), interval=0.8)
    try:
        supervisor.start()
        receive(sock, "READY=1")
        receive(sock, "WATCHDOG=1")
        http.hang.set()  # requests now hang: the server is alive but not serving
        time.sleep(0.8)
        _drain(sock)  # a ping already in flight when it hung
        time.sleep(1.5)
        assert _drain(sock) == []
        http.hang.clear()
        http.release.set()
        receive(sock, "WATCHDOG=1")
    finally:
        supervisor.close()
        http.close()
    assert "STOPPING=1" in receive(sock, "STOPPING=1")[-1]
    supervisor.close()  # idempotent


def _drain(sock):
    got = []
    while True:
        try:
            got.append(sock.recv(4096).decode())
        except socket.timeout:
            return got


def test_nothing_happens_outside_systemd():
    notifier = systemd.Notifier({})
    assert not notifier.enabled and notifier.notify("READY=1") is False
    supervisor = systemd.Supervisor("127.0.0.1", 1, notifier).start()
    supervisor.close()
    assert not supervisor.ready


def test_abstract_socket_names_and_watchdog_env():
    assert systemd.Notifier({"NOTIFY_SOCKET": "@sd/notify"}).address == "\0sd/notify"
    assert systemd.watchdog_interval({"WATCHDOG_USEC": "4000000"}) == 4.0
    assert systemd.watchdog_interval({"WATCHDOG_USEC": "4000000", "WATCHDOG_PID": "1"}) is None
    assert systemd.watchdog_interval({}) is None


def test_units_installed_before_the_move_still_stop_the_bridges(tmp_path):
    import subprocess
    import sys

    config = tmp_path / "robot.yaml"
    config.write_text("drive:\n  backend: none\n")
    proc = subprocess.run([sys.executable, "-m", "flask_move_server.app.systemd", "safe-stop", "--config", str(config)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and "no L298N pins" in proc.stdout
