"""One client connection of the HTTP server (waitress's channel and task), hardened.

- remembers when its current request began, so the server can close one that has not delivered
  a whole request within ``request_timeout``, sat idle for ``channel_timeout``, or left its
  answers unread for ``channel_timeout``
  (:meth:`RobotChannel.overdue`, :meth:`RobotChannel.waiting_since`);
- an event stream's unsent output is bounded (``STREAM_BACKLOG``): its writer waits instead, and
  a peer that takes nothing for ``channel_timeout`` is disconnected; the app can ask whether the
  peer left (``flask_move_server.peer_gone`` in the WSGI environ);
- waitress's own error answers (400, 413, 431, 501) come in the API's JSON error shape (a body
  announced too large gets its 413 at once, not ``100 Continue`` first), and the
  connection of a request refused midway closes only once the client is done sending, so the
  client reads the answer instead of a reset (:meth:`RobotChannel._linger`).
"""

import json
import socket
import time

from waitress.channel import ClientDisconnected, HTTPChannel
from waitress.task import ErrorTask, WSGITask

from flask_move_server.web.events import PEER_GONE

STREAM_TYPE = "text/event-stream"
STREAM_BACKLOG = 64 * 1024  # bytes of a stream's output that may wait unsent before its writer waits
UNREAD_LIMIT = 1024 * 1024  # bytes a refused request may still send before its connection is closed
LINGER_SECONDS = 2.0  # how long a refused request's connection waits for the client to finish sending

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
        self.response_headers.append(("Content-Type", "application/json; charset=utf-8"))
        self.response_headers.append(("Connection", "close"))  # waitress closes after an error
        self.close_on_finish = True
        self.channel.refused = True
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
    refused = False  # a JSON error answer was the last: the request may not have been read whole
    linger_until = None  # while set, the answer is sent and the client's remaining input is dropped
    linger_left = 0
    requests_parsed = 0
    unparsed = b""  # what a client pipelined after the request waiting to be served (see _parse)

    def __init__(self, server, sock, addr, adj, map=None):
        super().__init__(server, sock, addr, adj, map=map)
        if server.over_address_share(self):  # closed at the loop's next pass, nothing read
            self.will_close = True
            server.policy.refused_addresses += 1

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

    def handle_expt(self):
        """TCP urgent data, which no HTTP client sends: close the connection.

        Waitress only logs it ("unhandled incoming priority event") and leaves the byte unread, so
        one urgent byte kept the loop spinning at 100 % and logging ~60,000 lines a second until
        the connection timed out.
        """
        self._close_now()

    # readable() and writable() are asked of every connection on every pass of the loop: the
    # lingering test is inlined and waitress's own answer called directly (no super()), as the
    # wrappers alone took ~6 % of the server's time with 8 clients (py-spy --gil).
    def readable(self):
        if self.linger_until is not None:
            return True
        if self.unparsed and HTTPChannel.readable(self):
            self._parse_next()
        return HTTPChannel.readable(self)

    def writable(self):
        if self.linger_until is not None:
            return time.time() > self.linger_until  # then handle_write closes it
        return HTTPChannel.writable(self)

    def handle_read(self):
        if not self.lingering():
            return super().handle_read()
        try:
            data = self.socket.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except (OSError, AttributeError):  # the client reset the connection, or it is closed
            data = b""
        self.linger_left -= len(data)
        if not data or self.linger_left <= 0:
            self._close_now()

    def handle_write(self):
        if self.lingering():
            return self._close_now()  # LINGER_SECONDS are over
        return super().handle_write()

    def handle_close(self):
        if not self.lingering() and self.refused and self.connected and not self.total_outbufs_len:
            self._linger()
        else:
            self._close_now()

    def _linger(self):
        """After a refusal, send the FIN and read away what the client still sends, then close.

        A request refused midway (413 while its body is still coming, 400 on bad framing) leaves
        input unread; closing a TCP socket then makes Linux answer the client's next bytes with a
        reset, and a client still sending (requests sends a chunked body whole before it reads)
        sees "connection reset" instead of the JSON error. So the server shuts its side down and
        drops what arrives until the client closes, ``UNREAD_LIMIT`` bytes or ``LINGER_SECONDS``,
        whichever comes first (the lingering close of RFC 9112 section 9.6 and of nginx).
        """
        try:
            self.socket.shutdown(socket.SHUT_WR)
        except (OSError, AttributeError):
            return self._close_now()
        self.linger_left = UNREAD_LIMIT
        self.linger_until = time.time() + LINGER_SECONDS

    def lingering(self):
        """True while the answer is sent and the client's remaining input is being dropped."""
        return self.linger_until is not None

    def stop_lingering(self):
        """Close at the loop's next pass (to make room for other clients)."""
        if self.lingering():
            self.linger_until = 0.0

    def _close_now(self):
        self.linger_until = None
        super().handle_close()

    def send_continue(self):
        """No ``100 Continue`` for a request refused already (a Content-Length over the limit).

        Waitress sent it anyway, inviting the client to send the whole oversized body before its
        413; the refusal now comes at once.
        """
        if self.request is not None and self.request.error is not None:
            self.request.expect_continue = False
            return
        super().send_continue()

    def received(self, data):
        if data and self.request is None:
            self.request_began = time.time()
        if self.unparsed:
            data, self.unparsed = self.unparsed + data, b""
        return self._parse(data)

    def _parse_next(self):
        """The previous request is answered: parse the next one its client pipelined."""
        data, self.unparsed = self.unparsed, b""
        self.request_began = time.time()
        self._parse(data)

    def _parse(self, data):
        """Waitress's ``received``, stopping once a whole request waits to be served.

        Waitress parsed every request a client had pipelined as soon as it arrived (~220 in one
        read of 8 KB); a few hundred connections doing so made each pass of the loop take 0.3 s,
        and a new connection (the owner's ``/stop``) waited two passes to be read. What follows
        the waiting request stays unparsed in ``unparsed`` until it is answered.
        """
        if not data:
            return False
        with self.requests_lock:
            if self.will_close or self.close_when_flushed:
                return False
            while data:
                if self.requests and self.request is None:
                    self.unparsed = data
                    break
                if self.request is None:
                    self.request = self.parser_class(self.adj)
                n = self.request.received(data)
                if (self.request.expect_continue and self.request.headers_finished and not self.requests
                        and not self.sent_continue):
                    self.send_continue()
                if self.request.completed:
                    self.sent_continue = False
                    if not self.request.empty:
                        self.requests.append(self.request)
                        self.requests_parsed += 1
                        if len(self.requests) == 1:
                            self.server.add_task(self)
                    self.request = None
                if n >= len(data):
                    break
                data = data[n:]
        return True

    def waiting_since(self):
        """Since when this connection has waited on its client; None while the server works for it.

        Busy (None): a request queued or in service, or closing. Waiting: an answer the client does
        not read (since the last write that made progress: waitress's ``last_activity``), a request
        it has not finished sending (since it began), or nothing at all (since its last activity).
        A client that pipelines requests and never reads their answers is waiting, so it can be
        shed past ``connection_limit`` and cut by the timeouts like any idle or slow client.
        """
        if self.requests or self.will_close:
            return None
        if self.request is not None and not self.total_outbufs_len:
            return self.request_began
        return self.last_activity

    def overdue(self, now):
        """True when this connection should be closed by the timeouts."""
        since = self.waiting_since()
        if since is None:
            return False
        adj = self.server.policy
        if self.total_outbufs_len:  # an answer the client takes nothing of
            return now - since > adj.channel_timeout
        if self.request is not None or self.request_began is None:  # partial request, or nothing yet
            return now - since > adj.request_timeout
        return now - since > adj.channel_timeout
