"""The HTTP server: waitress, hardened for a robot anyone on the Wi-Fi can reach.

Waitress as it comes lets ~100 idle sockets lock every client out (it stops
accepting at ``connection_limit``), answers its own errors (400, 413, 431, 501)
in ``text/plain``, refuses a body of exactly the limit, and logs one warning
per queued request. This module builds the server from ``ServerConfig`` with:

- a connection policy: always accept; over ``connection_limit``, close the
  connections that have waited longest without a request in progress (idle,
  or a slow-loris still sending its headers); close a connection that has not
  delivered a whole request within ``request_timeout`` and a keep-alive one
  idle for ``channel_timeout``;
- a stop lane: ``POST /stop`` (and ``/estop``) jumps the request queue, and
  gets a spare thread when every worker is busy (a ``/goto`` with ``wait``
  holds one), so the owner can always stop the robot;
- a stream lane: each ``GET /events`` stream is served on a thread of its own (at most
  ``server.max_streams``), never on one of the ``server.threads`` workers, so open pages
  never delay ``/stop`` or anything else; a stream's unsent output is bounded
  (``STREAM_BACKLOG``): its writer waits instead, and a peer that takes nothing for
  ``channel_timeout`` is disconnected; the app can ask whether the peer left;
- errors in the API's JSON shape wherever waitress answers before the app;
- a rate-limited summary instead of one ``Task queue depth`` line per request.
"""

import json
import logging
import resource
import socket
import threading
import time

from waitress.adjustments import Adjustments
from waitress.channel import ClientDisconnected, HTTPChannel
from waitress.server import TcpWSGIServer
from waitress.task import ErrorTask, ThreadedTaskDispatcher, WSGITask

from flask_move_server.web.events import PEER_GONE

log = logging.getLogger(__name__)

URGENT = frozenset({("POST", "/stop"), ("POST", "/estop")})
STREAMS = frozenset({("GET", "/events")})
STREAM_TYPE = "text/event-stream"
STREAM_BACKLOG = 64 * 1024  # bytes of a stream's output that may wait unsent before its writer waits
SPARE_THREADS = 2  # extra threads the stop lane may start when every worker is busy
QUEUE_LOGGER = "waitress.queue"
QUEUE_SUMMARY_INTERVAL = 60.0
MAINTENANCE_INTERVAL = 1  # seconds between sweeps for timed-out connections

_ERRORS = {
    400: ("bad_request", "The request is not valid HTTP ({detail})."),
    413: ("body_too_large", "The request body is larger than {limit} bytes."),
    431: ("headers_too_large", "The request's headers are too large ({detail})."),
    500: ("internal_error", "The server failed unexpectedly; its log has the details."),
    501: ("not_implemented", "The server does not support this request ({detail})."),
}


class JsonErrorTask(ErrorTask):
    """Waitress's own error answers (bad framing, too large, ...) in the API's JSON error shape."""

    def execute(self):
        error = self.request.error
        limit = self.channel.server.max_body_bytes
        code, template = _ERRORS.get(error.code, ("error", "The request failed ({detail})."))
        message = template.format(detail=str(error.body).rstrip("."), limit=limit)
        body = json.dumps({"status": "error", "error": code, "message": message}).encode("utf-8")
        self.status = "{} {}".format(error.code, error.reason)
        self.response_headers.append(("Content-Type", "application/json"))
        self.response_headers.append(("Connection", "close"))  # waitress closes after an error
        self.close_on_finish = True
        self.content_length = len(body)
        self.write(body)


class RobotTask(WSGITask):
    """A request served by the app; an event stream's unsent writes never pile up.

    Waitress (2.x: ``send_bytes`` is 1) sends each write from the task's thread as it is made,
    the headers with the first body chunk, so an event goes out when the stream yields it.
    """

    _streaming = None

    def get_environment(self):
        environ = super().get_environment()
        environ[PEER_GONE] = self.channel.peer_gone
        return environ

    def write(self, data):
        if self._streaming is None:
            self._streaming = any(name.lower() == "content-type" and value.startswith(STREAM_TYPE)
                                  for name, value in self.response_headers)
            if self._streaming:
                self.channel.give_up_unacknowledged_after(self.channel.adj.channel_timeout)
        if self._streaming:
            self.channel.wait_for_backlog(STREAM_BACKLOG)
        super().write(data)  # sent from this thread at once (waitress 2's send_bytes is 1)


class RobotChannel(HTTPChannel):
    """One client connection; remembers when its current request began (for request_timeout)."""

    task_class = RobotTask
    error_task_class = JsonErrorTask
    request_began = None

    def peer_gone(self):
        """True once the client closed or reset the connection (peeked at, nothing read)."""
        if not self.connected or self.will_close:
            return True
        try:
            return self.socket.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
        except (BlockingIOError, InterruptedError):
            return False
        except (OSError, AttributeError):  # reset, or closed by the loop meanwhile
            return True

    def give_up_unacknowledged_after(self, seconds):
        """Let the kernel drop this connection when what it sent is unacknowledged for ``seconds``.

        A phone that left the Wi-Fi never answers; without this its stream would keep a thread
        until TCP's retransmissions give up (~15 minutes), as the heartbeats only fill the socket's
        buffer. Linux (TCP_USER_TIMEOUT); elsewhere the backlog rule of :meth:`wait_for_backlog`.
        """
        option = getattr(socket, "TCP_USER_TIMEOUT", None)
        if option is None:
            return
        try:
            self.socket.setsockopt(socket.IPPROTO_TCP, option, int(seconds * 1000))
        except (OSError, AttributeError):
            pass  # closed meanwhile: nothing left to time out

    def wait_for_backlog(self, limit):
        """Block the writing thread while more than ``limit`` bytes wait unsent.

        A peer that has taken nothing for ``channel_timeout`` seconds is disconnected
        (ClientDisconnected): a phone that walked out of Wi-Fi range frees its thread.
        """
        with self.outbuf_lock:
            while self.connected and self.total_outbufs_len > limit:
                if time.time() - self.last_activity > self.adj.channel_timeout:
                    self.will_close = True
                    self.server.pull_trigger()
                    raise ClientDisconnected("the client took nothing for {:.0f} s".format(self.adj.channel_timeout))
                self.server.pull_trigger()
                self.outbuf_lock.wait(1.0)

    def received(self, data):
        if data and self.request is None:
            self.request_began = time.time()
        return super().received(data)

    def waiting_since(self):
        """When this connection began to wait for something it has not finished sending; None if busy.

        Busy: a request is queued or in service, or its answer is still being sent.
        """
        if self.requests or self.total_outbufs_len or self.will_close:
            return None
        if self.request is not None:
            return self.request_began
        return self.last_activity

    def overdue(self, now):
        """True when this connection should be closed by the timeouts."""
        since = self.waiting_since()
        if since is None:
            return False
        adj = self.server.policy
        if self.request is not None or self.request_began is None:  # partial request, or nothing yet
            return now - since > adj.request_timeout
        return now - since > adj.channel_timeout


class StopLaneDispatcher(ThreadedTaskDispatcher):
    """Worker threads, with ``POST /stop`` served first and never stuck behind busy workers."""

    def __init__(self, max_streams=0):
        super().__init__()
        self._spares = threading.BoundedSemaphore(SPARE_THREADS)
        self._streams = threading.BoundedSemaphore(max_streams) if max_streams else None
        self._stream_threads = set()

    def add_task(self, task):
        line = _request_line(task)  # once: this runs on the event loop's thread, for every request
        if line in STREAMS and self._streams is not None and self._streams.acquire(blocking=False):
            thread = threading.Thread(target=self._serve_stream, args=(task,), name="waitress-event-stream",
                                      daemon=True)
            with self.lock:
                self._stream_threads.add(thread)
            thread.start()
            return
        if line not in URGENT:
            super().add_task(task)  # a stream past max_streams too: the app answers it 503 at once
            return
        with self.lock:
            idle = len(self.threads) - self.stop_count - self.active_count
            if idle > len(self.queue) or not self._spares.acquire(blocking=False):
                self.queue.appendleft(task)
                self.queue_cv.notify()
                return
        threading.Thread(target=self._serve_spare, args=(task,), name="waitress-stop-lane", daemon=True).start()

    def _serve_spare(self, task):
        try:
            task.service()
        except BaseException:
            self.logger.exception("Exception when servicing %r", task)
        finally:
            self._spares.release()

    def _serve_stream(self, task):
        try:
            task.service()
        except BaseException:
            self.logger.exception("Exception when servicing %r", task)
        finally:
            with self.lock:
                self._stream_threads.discard(threading.current_thread())
            self._streams.release()

    def join_streams(self, timeout):
        """Wait up to ``timeout`` s for the open streams' threads to end (their event bus is closed)."""
        deadline = time.monotonic() + timeout
        with self.lock:
            threads = list(self._stream_threads)
        for thread in threads:
            thread.join(max(0.0, deadline - time.monotonic()))


def _request_line(channel):
    requests = getattr(channel, "requests", None)
    if not requests:
        return None
    request = requests[0]
    return getattr(request, "command", None), getattr(request, "path", None)


class RobotWSGIServer(TcpWSGIServer):
    """Waitress's TCP server with the connection policy of this module."""

    channel_class = RobotChannel
    policy = None
    max_body_bytes = None

    def readable(self):
        now = time.time()
        if now >= self.next_channel_cleanup:
            self.next_channel_cleanup = now + self.adj.cleanup_interval
            self.maintenance(now)
        # Keep accepting past the limit (room is made in handle_accept), up to a hard ceiling.
        return self.accepting and len(self.active_channels) < 2 * self.adj.connection_limit

    def handle_accept(self):
        super().handle_accept()
        self.make_room()

    def make_room(self):
        """Over ``connection_limit``: close the connections that have waited longest for nothing.

        Closed as waitress closes: ``will_close``, acted on by the loop's next pass (closing a
        socket while the loop gathers its select() lists would hand select() a closed descriptor).
        """
        channels = list(self.active_channels.values())
        excess = len(channels) - sum(1 for c in channels if c.will_close) - self.adj.connection_limit
        if excess <= 0:
            return
        waiting = sorted((c.waiting_since(), id(c), c) for c in channels if c.waiting_since() is not None)
        for _, _, channel in waiting[:excess]:
            channel.will_close = True
        self.policy.shed += min(excess, len(waiting))

    def maintenance(self, now):
        """Close connections past request_timeout (no whole request yet) or channel_timeout (idle)."""
        for channel in list(self.active_channels.values()):
            if channel.overdue(now):
                channel.will_close = True


class ConnectionPolicy:
    """The timeouts and counters the server's connection policy uses."""

    def __init__(self, server_config):
        self.request_timeout = server_config.request_timeout
        self.channel_timeout = server_config.channel_timeout
        self.shed = 0


class QueueDepthSummary:
    """The dispatcher's ``queue_logger``: waitress's per-request ``Task queue depth`` warning is
    counted, and one summary per interval goes to the real ``waitress.queue`` logger.

    Counting, not filtering: a filtered warning still builds its log record first, and under a
    burst of requests that was 8 % of the server's Python time (``py-spy --gil``). Anything else
    waitress may ask of its logger goes to the real one.
    """

    def __init__(self, logger, interval=QUEUE_SUMMARY_INTERVAL, clock=time.monotonic):
        self._logger = logger
        self.interval = interval
        self._clock = clock
        self._lock = threading.Lock()
        self._count = self._deepest = 0
        self._window_start = None
        self._next = None

    def __getattr__(self, name):
        return getattr(self._logger, name)

    def warning(self, msg, *args, **kwargs):
        if not str(msg).startswith("Task queue depth"):
            self._logger.warning(msg, *args, **kwargs)
            return
        now = self._clock()
        with self._lock:
            if self._window_start is None:
                self._window_start = self._next = now
            self._count += 1
            self._deepest = max(self._deepest, args[0] if args else 0)
            if now < self._next:
                return
            summary = (self._count, max(now - self._window_start, 0.0), self._deepest)
            self._count = self._deepest = 0
            self._window_start, self._next = now, now + self.interval
        self._logger.warning("%d request(s) waited for a free worker thread in the last %.0f s (deepest queue: %d)",
                             *summary)


class HttpServer:
    """The running waitress server: ``run()`` until SystemExit, ``close()`` idempotently."""

    def __init__(self, app, server_config):
        self.policy = ConnectionPolicy(server_config)
        self.adj = Adjustments(**waitress_settings(server_config))
        _raise_fd_limit(2 * server_config.connection_limit + 256)
        self._map = {}
        self.dispatcher = StopLaneDispatcher(server_config.max_streams)
        self.dispatcher.set_thread_count(self.adj.threads)
        self.dispatcher.queue_logger = QueueDepthSummary(logging.getLogger(QUEUE_LOGGER))
        self._servers = [self._listen(app, sockinfo, server_config) for sockinfo in self.adj.listen]
        self.effective_host = self._servers[0].effective_host
        self.effective_port = self._servers[0].effective_port
        self._closed = False

    def _listen(self, app, sockinfo, server_config):
        server = RobotWSGIServer(app, map=self._map, dispatcher=self.dispatcher, adj=self.adj, sockinfo=sockinfo)
        server.policy = self.policy
        server.max_body_bytes = server_config.max_body_bytes
        return server

    def run(self):
        """Serve until SystemExit/KeyboardInterrupt; then let busy workers finish (waitress: up to 5 s)."""
        self._servers[0].run()

    def stop(self):
        """End :meth:`run` from another thread (tests, embedding): close from inside the loop, drain."""
        if not self._closed:
            self._servers[0].trigger.pull_trigger(self.close)
        self.dispatcher.shutdown()

    def finish_streams(self, timeout=2.0):
        """The server is stopping and the event bus is closed: let each stream write its end, and send it.

        A stream's last chunk is written by its own thread into the connection's buffer, which
        waitress's loop sends; the loop has stopped by now, so without this the connections were
        dropped with the end unsent now and then, and a page saw a cut stream, not a clean end.
        """
        self.dispatcher.join_streams(timeout)
        for channel in list(self._map.values()):
            if isinstance(channel, RobotChannel) and channel.total_outbufs_len:
                with channel.outbuf_lock:
                    channel._flush_some(do_close=False)  # non-blocking: what the socket takes now

    def close(self):
        """Stop listening and drop every connection. Idempotent."""
        if self._closed:
            return
        self._closed = True
        for channel in list(self._map.values()):
            if isinstance(channel, RobotChannel):
                channel.close()
        for server in self._servers:
            server.close()


def waitress_settings(server_config):
    """Waitress's Adjustments for ``server_config``."""
    return dict(
        host=server_config.host,
        port=server_config.port,
        threads=server_config.threads,
        connection_limit=server_config.connection_limit,
        channel_timeout=server_config.channel_timeout,
        cleanup_interval=MAINTENANCE_INTERVAL,
        # waitress refuses a body of exactly its limit; the API's limit includes max_body_bytes itself
        max_request_body_size=server_config.max_body_bytes + 1,
        ident="flask-move-server",
        clear_untrusted_proxy_headers=True,
    )


def _raise_fd_limit(wanted):
    """Raise the soft open-files limit towards ``wanted`` (sockets are files); warn when it cannot."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY or soft >= wanted:
        return
    target = wanted if hard == resource.RLIM_INFINITY else min(wanted, hard)
    try:
        resource.setrlimit(resource.RLIMIT_NOFILE, (target, hard))
    except (ValueError, OSError):
        target = soft
    if target < wanted:
        log.warning("the open-files limit is %d, below the %d that server.connection_limit needs; "
                    "raise it (systemd: LimitNOFILE=) or lower connection_limit", target, wanted)
