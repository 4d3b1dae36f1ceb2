"""One client connection of the HTTP server (waitress's channel and task), hardened.

- remembers when its current request began, so the server can close one that has not delivered
  a whole request within ``request_timeout`` or sat idle for ``channel_timeout``
  (:meth:`RobotChannel.overdue`, :meth:`RobotChannel.waiting_since`);
- an event stream's unsent output is bounded (``STREAM_BACKLOG``): its writer waits instead, and
  a peer that takes nothing for ``channel_timeout`` is disconnected; the app can ask whether the
  peer left (``flask_move_server.peer_gone`` in the WSGI environ);
- waitress's own error answers (400, 413, 431, 501) come in the API's JSON error shape.
"""

import json
import socket
import time

from waitress.channel import ClientDisconnected, HTTPChannel
from waitress.task import ErrorTask, WSGITask

from flask_move_server.web.events import PEER_GONE

STREAM_TYPE = "text/event-stream"
STREAM_BACKLOG = 64 * 1024  # bytes of a stream's output that may wait unsent before its writer waits
UNREAD_LIMIT = 256 * 1024  # bytes of a closing connection's unread input read away, so it closes with a FIN

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

    def handle_close(self):
        self._read_away_unread()
        super().handle_close()

    def _read_away_unread(self):
        """Read (and drop) what the client sent that nobody will read, just before the socket closes.

        Closing a TCP socket with unread data makes Linux send a reset instead of a FIN, and the
        reset can reach the client before it reads the answer: a body refused with 413 while its
        last chunk was still arriving showed as "connection reset by peer", not the JSON error
        (1 run in 4). Bounded and non-blocking: at most ``UNREAD_LIMIT`` bytes.
        """
        sock, left = self.socket, UNREAD_LIMIT
        try:
            while sock is not None and left > 0:
                data = sock.recv(min(left, 65536), socket.MSG_DONTWAIT)
                if not data:
                    return
                left -= len(data)
        except OSError:  # nothing more waiting (EAGAIN), or the peer is gone already
            pass

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
