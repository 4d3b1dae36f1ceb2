"""The hardened waitress server (flask_move_server.http.server) with the real app, real sockets.

Errors waitress answers before the app are JSON, the body limit is exact,
silent and slow connections are cut, and waitress's per-request queue warnings
become one summary.
"""

import contextlib
import json
import logging
import os
import re
import resource
import socket
import time
from concurrent.futures import ThreadPoolExecutor

import pytest
import requests

from flask_move_server.http.connection import LINGER_SECONDS, UNREAD_LIMIT
from tests.conftest import hardened, wait_for
from tests.standins.move_base import HOLD_X


def raw(url, data, timeout=10):
    """Send ``data`` on a fresh connection; the whole answer (status line, headers, body)."""
    host, port = url.split("//")[1].split(":")
    with socket.create_connection((host, int(port)), timeout=timeout) as sock:
        sock.sendall(data)
        chunks = []
        while True:
            chunk = sock.recv(65536)
            if not chunk:
                break
            chunks.append(chunk)
    head, _, body = b"".join(chunks).partition(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    headers = dict(line.split(": ", 1) for line in lines[1:])
    return int(lines[0].split()[1]), headers, body


@pytest.fixture
def served(app, robot_config):
    with hardened(app, robot_config.server) as (server, url):
        yield url


@pytest.mark.parametrize("request_bytes, status, code", [
    (b"get /status HTTP/1.1\r\nHost: robot\r\n\r\n", 400, "bad_request"),
    (b"GET /status HTTP/1.1\r\nHost: robot\r\nBad Header\r\n\r\n", 400, "bad_request"),
    (b"POST /goto HTTP/1.1\r\nHost: robot\r\nTransfer-Encoding: gzip\r\n\r\n", 501, "not_implemented"),
    (b"POST /goto HTTP/1.1\r\nHost: robot\r\nContent-Length: 16385\r\n\r\n", 413, "body_too_large"),
    (b"POST /goto HTTP/1.1\r\nHost: robot\r\nTransfer-Encoding: chunked\r\n\r\nzz\r\n", 400, "bad_request"),
])
def test_errors_waitress_answers_before_the_app_are_json(served, request_bytes, status, code):
    got, headers, body = raw(served, request_bytes)
    assert got == status
    assert headers["Content-Type"] == "application/json; charset=utf-8"
    answer = json.loads(body)
    assert answer["status"] == "error" and answer["error"] == code and answer["message"].endswith(".")


def _padded(limit, extra=0):
    body = b'{"x": 1.0, "y": 2.0, "yaw": 0.5}'
    return body + b" " * (limit - len(body) + extra)


def test_a_body_of_exactly_max_body_bytes_is_accepted_and_one_more_byte_is_a_json_413(served, robot_config):
    limit = robot_config.server.max_body_bytes
    exact = requests.put(served + "/waypoints/porch", data=_padded(limit), timeout=10)
    assert exact.status_code == 201, exact.text
    over = requests.put(served + "/waypoints/porch", data=_padded(limit, 1), timeout=10)
    assert over.status_code == 413 and over.json()["error"] == "body_too_large"
    assert str(limit) in over.json()["message"]


def test_expect_100_continue_with_a_body_over_the_limit_gets_the_413_at_once(served, robot_config):
    host, port = served.split("//")[1].split(":")
    with socket.create_connection((host, int(port)), timeout=10) as sock:
        sock.sendall(b"PUT /waypoints/porch HTTP/1.1\r\nHost: 127.0.0.1\r\nExpect: 100-continue\r\n"
                     b"Content-Length: " + str(robot_config.server.max_body_bytes + 1).encode() + b"\r\n\r\n")
        answer = _read_to_end(sock)
    assert answer.startswith(b"HTTP/1.1 413") and b"100 Continue" not in answer
    assert json.loads(answer.partition(b"\r\n\r\n")[2])["error"] == "body_too_large"


def test_a_chunked_body_is_read_whole_and_one_past_the_limit_is_a_json_413(served, robot_config):
    limit = robot_config.server.max_body_bytes

    def chunked(body):  # requests sends a generator with Transfer-Encoding: chunked
        for i in range(0, len(body), 1000):
            yield body[i:i + 1000]

    # waitress counts the chunks' framing against the limit too, so a chunked body falls short of it
    whole = requests.put(served + "/waypoints/porch", data=chunked(_padded(limit - 200)), timeout=10)
    assert whole.status_code == 201, whole.text
    assert requests.get(served + "/waypoints/porch", timeout=10).json() == {"name": "porch", "x": 1.0, "y": 2.0,
                                                                           "yaw": 0.5}
    over = requests.put(served + "/waypoints/porch", data=chunked(_padded(limit, 1)), timeout=10)
    assert over.status_code == 413 and over.json()["error"] == "body_too_large"


def _read_to_end(client):
    answer = b""
    while True:
        chunk = client.recv(65536)  # ConnectionResetError when the server reset the connection
        if not chunk:
            return answer
        answer += chunk


def test_a_refused_body_still_in_flight_gets_the_answer_not_a_reset(served, robot_config):
    """The server answers 413 and closes while the client's body still waits unread in its socket;
    closed so, Linux resets the connection and the client may never read the answer."""
    port = int(served.rsplit(":", 1)[1])
    for _ in range(5):
        with socket.create_connection(("127.0.0.1", port), timeout=10) as client:
            client.sendall("PUT /waypoints/porch HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json"
                           "\r\nContent-Length: {}\r\n\r\n".format(robot_config.server.max_body_bytes + 1)
                           .encode() + b" " * 65536)  # far more than the server reads before it refuses
            time.sleep(0.2)  # the answer is sent and the connection closed by now
            answer = _read_to_end(client)
        assert answer.startswith(b"HTTP/1.1 413") and b'"error": "body_too_large"' in answer


def _refused_chunked_upload(port, limit):
    """A connection that has sent a chunked PUT one chunk past ``limit``, the body not yet ended."""
    client = socket.create_connection(("127.0.0.1", port), timeout=10)
    client.sendall(b"PUT /waypoints/porch HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json"
                   b"\r\nTransfer-Encoding: chunked\r\n\r\n")
    for _ in range(limit // 1000 + 1):
        client.sendall(b"3e8\r\n" + b" " * 1000 + b"\r\n")
    time.sleep(0.3)  # the server has answered 413 by now
    return client


def test_a_client_still_sending_a_refused_body_reads_the_answer_not_a_reset(served, robot_config):
    """requests sends a chunked body whole before it reads: its chunks after the 413 must not be reset."""
    port = int(served.rsplit(":", 1)[1])
    for _ in range(3):
        with _refused_chunked_upload(port, robot_config.server.max_body_bytes) as client:
            client.sendall(b"3e8\r\n" + b" " * 1000 + b"\r\n")
            time.sleep(0.1)
            client.sendall(b"0\r\n\r\n")  # BrokenPipeError when the server closed without lingering
            answer = _read_to_end(client)
        assert answer.startswith(b"HTTP/1.1 413") and b'"error": "body_too_large"' in answer


def test_a_refused_client_cannot_hold_its_connection_by_sending_or_by_silence(served, robot_config):
    port = int(served.rsplit(":", 1)[1])
    limit = robot_config.server.max_body_bytes
    with _refused_chunked_upload(port, limit) as silent:
        started = time.monotonic()
        assert _read_to_end(silent).startswith(b"HTTP/1.1 413")  # the answer, then the server's FIN
        silent.sendall(b"3e8\r\n")  # the connection stays open for the rest of the body ...
        time.sleep(LINGER_SECONDS + 2)  # ... for LINGER_SECONDS, plus the server loop's sleep
        with pytest.raises(OSError):  # then it is closed: the late bytes are answered with a reset
            for _ in range(10):
                silent.sendall(b" " * 1000)
                time.sleep(0.05)
        assert time.monotonic() - started < 15
    with _refused_chunked_upload(port, limit) as endless:
        sent = 0
        with pytest.raises(OSError):
            while sent < 20 * UNREAD_LIMIT:
                endless.sendall(b"3e8\r\n" + b" " * 1000 + b"\r\n")
                sent += 1006
        assert sent < 20 * UNREAD_LIMIT, "the server kept reading a refused body without end"


def test_a_burst_of_refused_requests_lingering_does_not_lock_other_clients_out(app, robot_config):
    robot_config.server.connection_limit = 4  # the server stops accepting at twice the limit
    limit = robot_config.server.max_body_bytes
    with hardened(app, robot_config.server) as (server, url):
        port = int(url.rsplit(":", 1)[1])
        refused = []
        try:
            for _ in range(8):
                client = socket.create_connection(("127.0.0.1", port), timeout=10)
                refused.append(client)
                client.sendall(b"PUT /waypoints/porch HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: "
                               + str(limit + 1).encode() + b"\r\n\r\n" + b" " * (limit + 1))
                assert _read_to_end(client).startswith(b"HTTP/1.1 413")  # answered; it lingers, open
            answer = requests.get(url + "/health", timeout=LINGER_SECONDS / 2)  # before any lingering ends
            assert answer.status_code == 200
        finally:
            for client in refused:
                client.close()


def _length(answer):
    head = answer.partition(b"\r\n\r\n")[0].decode("latin-1").lower()
    return int(head.split("content-length: ")[1].split("\r\n")[0])


def test_clients_that_never_read_their_answers_cannot_lock_others_out(app, robot_config):
    """Pipelined requests whose answers are never read (more than the sockets' buffers hold) used to
    make a connection count as busy for ever: never shed past the limit, never timed out, so a
    handful of them (no token needed) left every new client, the owner's /stop included, unanswered."""
    robot_config.server.connection_limit = 4  # the server stops accepting at twice the limit
    pipeline = b"GET /openapi.json HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n" * 200
    with hardened(app, robot_config.server) as (server, url):
        port = int(url.rsplit(":", 1)[1])
        stalled = []
        try:
            for _ in range(10):
                client = socket.create_connection(("127.0.0.1", port), timeout=10)
                client.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
                client.setblocking(False)
                with contextlib.suppress(BlockingIOError):
                    client.sendall(pipeline)
                stalled.append(client)
            wait_for(lambda: sum(c.total_outbufs_len > 0 for c in list(server._map.values())
                                 if hasattr(c, "total_outbufs_len")) >= 4, timeout=10,
                     message="answers piling up unread")
            answer = requests.post(url + "/stop", timeout=5)  # the owner's stop gets through
            assert answer.status_code == 200
            assert server.policy.shed > 0
        finally:
            for client in stalled:
                client.close()


def test_one_urgent_byte_closes_its_connection_instead_of_spinning_the_server(served, caplog):
    port = int(served.rsplit(":", 1)[1])
    with socket.create_connection(("127.0.0.1", port), timeout=5) as client:
        client.sendall(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        answer = b""
        while b"\r\n\r\n" not in answer or len(answer.partition(b"\r\n\r\n")[2]) < _length(answer):
            answer += client.recv(65536)
        assert answer.startswith(b"HTTP/1.1 200")  # served whole; the connection is kept alive
        client.send(b"!", socket.MSG_OOB)
        try:
            closed = client.recv(65536) == b""  # socket.timeout when it was left open (and spinning)
        except ConnectionResetError:  # the urgent byte was unread: the close is a reset
            closed = True
        assert closed
    assert requests.get(served + "/health", timeout=5).status_code == 200
    assert not [r for r in caplog.records if "priority event" in r.getMessage()]


def test_a_connection_numbered_past_1024_is_served(served):
    """select() cannot watch descriptor 1024 or more; the server's loop died on one such connection."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft != resource.RLIM_INFINITY and soft < 1200:
        resource.setrlimit(resource.RLIMIT_NOFILE, (1200 if hard == resource.RLIM_INFINITY else min(1200, hard), hard))
    spare = []
    try:
        while not spare or spare[-1] < 1030:  # the server (in this process) takes the next numbers
            spare.append(os.open(os.devnull, os.O_RDONLY))
        answer = requests.get(served + "/health", timeout=5)
        assert answer.status_code == 200
    finally:
        for fd in spare:
            os.close(fd)
    assert requests.get(served + "/health", timeout=5).status_code == 200  # and the loop lives on


def test_silent_and_slow_connections_are_closed_after_request_timeout(app, robot_config):
    robot_config.server.request_timeout = 1.0
    with hardened(app, robot_config.server) as (server, url):
        port = int(url.rsplit(":", 1)[1])
        silent = socket.create_connection(("127.0.0.1", port))
        slow = socket.create_connection(("127.0.0.1", port))
        silent.settimeout(15)
        slow.settimeout(0.3)
        started = time.monotonic()
        closed = None
        with silent, slow:
            for byte in b"GET /status HTTP/1.1\r\nHost: robot\r\nX-Slow: " + b"a" * 100:
                with contextlib.suppress(socket.timeout):
                    if slow.recv(1024) == b"":
                        closed = time.monotonic() - started
                        break
                with contextlib.suppress(OSError):
                    slow.send(bytes([byte]))
            assert closed is not None and closed < 15, "the slow-loris connection stayed open"
            assert silent.recv(1024) == b"", "the silent connection stayed open"
        # the server still serves
        assert requests.get(url + "/health", timeout=5).status_code == 200


class Records(logging.Handler):
    def __init__(self):
        super().__init__()
        self.messages = []

    def emit(self, record):
        self.messages.append(record.getMessage())


def test_queued_requests_log_one_summary_not_one_line_each(app, robot_config, ready_robot):
    robot_config.server.threads = 1
    queue_log = logging.getLogger("waitress.queue")
    records = Records()
    queue_log.addHandler(records)
    try:
        with hardened(app, robot_config.server) as (server, url):
            holder = ThreadPoolExecutor(1)
            waiting = holder.submit(requests.post, url + "/goto", json={"x": HOLD_X, "y": 0.0, "wait": 30},
                                    timeout=60)
            wait_for(lambda: ready_robot.navigator.active, message="the goal holding the only worker")
            with ThreadPoolExecutor(20) as pool:
                answers = [pool.submit(requests.get, url + "/waypoints", timeout=60) for _ in range(40)]
                time.sleep(1)  # every request has reached the queue
                assert requests.post(url + "/stop", timeout=10).status_code == 200
                assert all(a.result().status_code == 200 for a in answers)
            assert waiting.result().status_code == 409
            holder.shutdown()
    finally:
        queue_log.removeHandler(records)
    assert 1 <= len(records.messages) <= 2, records.messages
    assert "waited for a free worker thread" in records.messages[0]


def test_one_address_holds_at_most_its_share_of_connections():
    """Hundreds of pipelining connections from one machine made the loop parse thousands of requests
    before it reached the owner's /stop; an address past ``connections_per_address`` is refused."""
    from types import SimpleNamespace

    from flask_move_server.http.server import RobotWSGIServer

    def channel(host):
        return SimpleNamespace(addr=(host, 40000))

    crowd = {i: channel("192.168.1.66") for i in range(3)}
    server = SimpleNamespace(active_channels=dict(crowd, phone=channel("192.168.1.20")),
                             policy=SimpleNamespace(per_address=3))
    share = RobotWSGIServer.over_address_share
    assert share(server, channel("192.168.1.66"))          # a fourth from the same machine
    assert not share(server, crowd[0])                      # the ones it has are its share
    assert not share(server, channel("192.168.1.20"))      # the owner's phone: its second
    server.active_channels.update({i + 10: channel("127.0.0.1") for i in range(5)})
    assert not share(server, channel("127.0.0.1"))          # this machine (a reverse proxy): not counted
    assert not share(server, SimpleNamespace(addr="/run/robot.sock"))  # a unix socket: no address


def test_pipelined_requests_are_each_answered_in_order(served):
    """What a client pipelines after the request in service is parsed once that one is answered:
    every request still gets its own answer, in order, a body split across packets included."""
    host, port = served.split("//")[1].split(":")
    body = b'{"x": 1.5, "y": -0.5, "yaw": 0.0}'
    put = (b"PUT /waypoints/porch HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
           b"Content-Length: " + str(len(body)).encode() + b"\r\n\r\n" + body)
    health = b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
    pipeline = health * 60 + put + b"GET /waypoints/porch HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"
    with socket.create_connection((host, int(port)), timeout=10) as sock:
        for i in range(0, len(pipeline), 997):  # packets that end mid-request
            sock.sendall(pipeline[i:i + 997])
            time.sleep(0.001)
        sock.sendall(b"GET /health HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n")
        answer = b""
        while True:
            chunk = sock.recv(65536)
            if not chunk:
                break
            answer += chunk
    statuses = [int(code) for code in re.findall(rb"HTTP/1\.1 (\d{3}) ", answer)]
    assert statuses == [200] * 60 + [201, 200, 200]
    assert answer.count(b'"x":1.5') == 2  # the waypoint stored, and read back by the GET after it


def test_connections_that_keep_pipelining_cannot_lock_the_owner_out(app, robot_config):
    """Connections pipelining requests (cheap 401s), reading each batch's answers and sending the next,
    are never idle, so they were never closed to make room: past twice ``connection_limit`` the
    server accepted nothing more and the owner's /stop was never answered. The address holding
    the most connections now gives up its oldest ones that have had answers."""
    from tests.hostile import PipelineFlood

    robot_config.server.connection_limit = 4  # the server stops accepting at twice the limit
    robot_config.server.token = "owner-secret"
    with hardened(app, robot_config.server) as (server, url):
        port = int(url.rsplit(":", 1)[1])
        with PipelineFlood("127.0.0.1", port, count=16, depth=50, max_seconds=60) as flood:
            wait_for(lambda: flood.answers > 500, timeout=20, message="the flood under way")
            answer = requests.post(url + "/stop", headers={"Authorization": "Bearer owner-secret"}, timeout=10)
            assert answer.status_code == 200
            assert server.policy.shed > 0
