"""A hostile client without a token: holds many TCP connections open to a server.

Half of them stay idle after connecting; the other half are slow-loris
clients that send a request line one byte at a time and never finish it. A
connection the server closes is opened again, so the count stays near ``count``
for as long as the client runs (as an attacker's would). Used by the tests and
by bench/bench_abuse.py. Loopback only; the run is bounded by ``max_seconds``.
And a hostile webhook receiver (``HostileReceiver``): an endless answer, or one a byte at a time.
"""

import select
import socket
import threading
import time

SLOW_REQUEST = b"GET /status HTTP/1.1\r\nHost: robot\r\nX-Slow: " + b"a" * 4000


class HostileClients:
    """``count`` connections to ``(host, port)`` held open by one background thread."""

    def __init__(self, host, port, count=300, drip_interval=0.5, max_seconds=120):
        self.address = (host, port)
        self.count = count
        self.drip_interval = drip_interval
        self.max_seconds = max_seconds
        self.reconnects = 0
        self._socks = []  # [socket, slow, bytes sent]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="hostile-clients", daemon=True)

    def __enter__(self):
        for i in range(self.count):
            self._socks.append(self._open(slow=i % 2 == 1))
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self.close()

    def open_count(self):
        return sum(1 for s in self._socks if s[0] is not None)

    def _open(self, slow):
        try:
            sock = socket.create_connection(self.address, timeout=2)
            sock.setblocking(False)
        except OSError:
            sock = None
        return [sock, slow, 0]

    def _run(self):
        deadline = time.monotonic() + self.max_seconds
        while not self._stop.wait(self.drip_interval) and time.monotonic() < deadline:
            self._reopen_closed()
            self._drip()

    def _reopen_closed(self):
        live = [s[0] for s in self._socks if s[0] is not None]
        readable = select.select(live, [], [], 0)[0] if live else []
        closed = set()
        for sock in readable:
            try:
                if not sock.recv(65536):
                    closed.add(sock)
            except OSError:
                closed.add(sock)
        for i, entry in enumerate(self._socks):
            if entry[0] is None or entry[0] in closed:
                if entry[0] is not None:
                    entry[0].close()
                    self.reconnects += 1
                self._socks[i] = self._open(entry[1])

    def _drip(self):
        for entry in self._socks:
            sock, slow, sent = entry
            if not slow or sock is None or sent >= len(SLOW_REQUEST):
                continue
            try:
                entry[2] += sock.send(SLOW_REQUEST[sent:sent + 1])
            except OSError:
                pass  # closed by the server: reopened on the next round

    def close(self):
        """Stop the thread and close every connection. Idempotent."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(5)
        for entry in self._socks:
            if entry[0] is not None:
                entry[0].close()
                entry[0] = None


class PipelineFlood:
    """``count`` connections that each send ``depth`` pipelined requests without a token, read the
    answers (cheap 401s) and send the next batch, for as long as the flood runs. One thread."""

    REQUEST = b"GET /status HTTP/1.1\r\nHost: robot\r\n\r\n"

    def __init__(self, host, port, count=300, depth=50, max_seconds=60):
        self.address = (host, port)
        self.count = count
        self.depth = depth
        self.batch = self.REQUEST * depth
        self.max_seconds = max_seconds
        self.answers = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="pipeline-flood", daemon=True)

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join(10)

    def _open(self):
        try:
            sock = socket.create_connection(self.address, timeout=2)
            sock.sendall(self.batch)
            sock.setblocking(False)
            return sock
        except OSError:
            return None

    def _run(self):
        owed = {}  # socket -> answers still to come for its batch
        for _ in range(self.count):
            self._replace(None, owed)
        deadline = time.monotonic() + self.max_seconds
        try:
            while not self._stop.is_set() and time.monotonic() < deadline and owed:
                for sock in select.select(list(owed), [], [], 0.1)[0]:
                    self._read(sock, owed)
        finally:
            for sock in owed:
                sock.close()

    def _read(self, sock, owed):
        try:
            data = sock.recv(65536)
        except OSError:
            data = b""
        if not data:
            return self._replace(sock, owed)
        answers = data.count(b"HTTP/1.1 ")
        self.answers += answers
        owed[sock] -= answers
        if owed[sock] <= 0:  # the whole batch answered: the next one
            try:
                sock.sendall(self.batch)
                owed[sock] = self.depth
            except OSError:
                self._replace(sock, owed)

    def _replace(self, sock, owed):
        if sock is not None:
            owed.pop(sock, None)
            sock.close()
        fresh = self._open()
        if fresh is not None:
            owed[fresh] = self.depth


class HostileReceiver:
    """A webhook receiver that answers 200 and then a body without end, at most ``limit`` bytes a connection
    (``trickle``: or sends its answer a byte at a time, every ``trickle`` s, never finishing the headers), on a
    raw socket of 127.0.0.1; counts what it sent (``sent``) and the connections (issue 34)."""

    def __init__(self, trickle=None, limit=2 ** 40):
        import socket

        self.trickle, self.limit, self.sent, self.connections = trickle, limit, 0, 0
        self._stop = threading.Event()
        self._server = socket.socket()
        self._server.bind(("127.0.0.1", 0))
        self._server.listen(8)
        self._server.settimeout(0.2)
        self.url = "http://127.0.0.1:{}/api/webhook/secret-id".format(self._server.getsockname()[1])
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self):
        import socket

        while not self._stop.is_set():
            try:
                conn, _ = self._server.accept()
            except socket.timeout:
                continue
            self.connections += 1
            threading.Thread(target=self._answer, args=(conn,), daemon=True).start()

    def _answer(self, conn):
        conn.settimeout(0.5)
        try:
            conn.recv(65536)
            if self.trickle:
                for byte in b"HTTP/1.1 200 OK\r\nX-Slow: " + b"y" * 10000:
                    if self._stop.wait(self.trickle):
                        return
                    conn.sendall(bytes([byte]))
                    self.sent += 1
                return
            conn.sendall(b"HTTP/1.1 200 OK\r\nContent-Type: application/octet-stream\r\n\r\n")
            chunk, sent = b"x" * 65536, 0
            while not self._stop.is_set() and sent < self.limit:
                conn.sendall(chunk)
                self.sent, sent = self.sent + len(chunk), sent + len(chunk)
        except OSError:
            pass  # the robot closed the connection
        finally:
            conn.close()

    def close(self):
        self._stop.set()
        self._thread.join(2)
        self._server.close()
