"""``GET /events``: the robot's state as Server-Sent Events, for the phone page.

Each event is ``event: <kind>`` and ``data: <one JSON object>`` (docs/api.md lists the kinds).
A new stream first gets the latest state of every kind (so a page draws at once, and a
reconnecting one catches up: events carry state, never deltas), then each change as the
event bus tells it. A slow reader never queues: its subscription keeps the newest event of
each kind only. A ``clock`` event every ``heartbeat`` seconds, however busy the stream, tells the
robot's clock (the one ``valid_until`` is read against, see web/deadline.py) and lets a reader tell
within seconds that the link went silent; it also keeps proxies from closing an idle stream and
makes a write to a vanished peer fail, freeing its thread; where the HTTP
server can tell (``flask_move_server.peer_gone`` in the WSGI environ, see http/connection.py),
a peer that closed the connection is noticed within ``poll`` seconds.

Each open stream holds a worker thread for as long as it is open, so at most
``server.max_streams`` are served at a time, at most half of them to one address (one more
answers 503 ``too_many_streams``),
and the HTTP server has that many threads more than ``server.threads``. A stream ends when
the event bus closes (the server is stopping), so it never delays SIGTERM.
Authorised like every route: the page reads it with ``fetch()`` and an ``Authorization``
header (EventSource cannot send one, and a token never goes in a URL).
"""

import ipaddress
import json
import threading
import time

from flask import Blueprint, Response, current_app, request

from flask_move_server.core.errors import TooManyStreams
from flask_move_server.web.deadline import robot_clock

events_api = Blueprint("events", __name__)

HEARTBEAT = 2.0  # s between clock events: a page leaves "live" after a few of them are missed
POLL = 0.5  # s: how often a quiet stream looks whether its peer left or the server is stopping
PEER_GONE = "flask_move_server.peer_gone"  # WSGI environ key: a callable, True once the client left
RETRY_MS = 2000  # the reconnection delay the stream suggests to SSE clients


class StreamGate:
    """How many streams may be open (``max_streams``, at most half of them from one address), and their timing.

    The per-address share keeps one machine on the Wi-Fi that opens streams and never reads them
    from taking every place (the owner's phone would get none); addresses on this machine (a
    reverse proxy, the tests) are not counted per address.
    """

    def __init__(self, max_streams, heartbeat=HEARTBEAT, poll=POLL, per_peer=None):
        self.max_streams = max_streams
        self.per_peer = per_peer if per_peer is not None else max(1, max_streams // 2)
        self.heartbeat = heartbeat
        self.poll = min(poll, heartbeat)
        self._lock = threading.Lock()
        self.open = 0
        self._by_peer = {}

    def enter(self, peer=None):
        """Count one more open stream from ``peer``; TooManyStreams when all, or the peer's share, are taken.

        Returns the key to give back to :meth:`leave` (None when not counted per address).
        """
        key = None if peer is None or ipaddress.ip_address(peer).is_loopback else peer
        with self._lock:
            if self.open >= self.max_streams:
                raise TooManyStreams(
                    "{} live views are open already, the most this robot serves (server.max_streams). "
                    "Close a page on another phone or tab, or wait for it to time out, then "
                    "reload.".format(self.max_streams))
            if key is not None and self._by_peer.get(key, 0) >= self.per_peer:
                raise TooManyStreams(
                    "{} live views are open from {} already, the most one address may hold (half of "
                    "server.max_streams). Close a page or tab there, then reload.".format(self.per_peer, key))
            self.open += 1
            if key is not None:
                self._by_peer[key] = self._by_peer.get(key, 0) + 1
        return key

    def leave(self, key=None):
        with self._lock:
            self.open -= 1
            if key is not None:
                left = self._by_peer.pop(key) - 1
                if left:
                    self._by_peer[key] = left


@events_api.record_once
def _set_up(state):
    shared = state.app.extensions["flask_move_server"]
    shared.setdefault("streams", StreamGate(shared["config"].server.max_streams))


@events_api.route("/events", methods=["GET"])
def stream():
    shared = current_app.extensions["flask_move_server"]
    gate = shared["streams"]
    place = gate.enter(request.remote_addr)
    body = EventStream(shared["events"].subscribe(), gate, request.environ.get(PEER_GONE), place)
    return Response(body, mimetype="text/event-stream",
                    headers={"Cache-Control": "no-store", "X-Accel-Buffering": "no"})


class EventStream:
    """The response body of one stream: an iterable of SSE chunks, closed once by the server.

    A class rather than a generator because the WSGI server calls ``close()`` even when it never
    started iterating (the client left at once): the gate's place and the subscription are
    given back either way.
    """

    def __init__(self, subscription, gate, peer_gone=None, place=None):
        self._sub = subscription
        self._gate = gate
        self._place = place
        self._peer_gone = peer_gone or (lambda: False)
        self._closed = False

    def __iter__(self):
        # The first chunk is written at once: the HTTP server sends the headers with it.
        yield ("retry: {}\n\n".format(RETRY_MS) + clock_event() + self._pending()).encode("utf-8")
        clock_told = time.monotonic()
        while not self._closed:
            item = self._sub.next(self._gate.poll)
            chunk = format_event(*item) + self._pending() if item is not None else ""
            if not chunk and (self._sub.closed or self._peer_gone()):
                return
            if time.monotonic() - clock_told >= self._gate.heartbeat:
                chunk += clock_event()
                clock_told = time.monotonic()
            if chunk:
                yield chunk.encode("utf-8")

    def _pending(self):
        """Every event waiting now, formatted: one write for a burst (the priming on connect)."""
        chunks = []
        item = self._sub.next(0)
        while item is not None:
            chunks.append(format_event(*item))
            item = self._sub.next(0)
        return "".join(chunks)

    def close(self):
        """The server is done with this stream (ended, client gone, or stopping). Idempotent."""
        if self._closed:
            return
        self._closed = True
        self._sub.close()
        self._gate.leave(self._place)


def clock_event():
    """The robot's clock now, as a ``clock`` event: ``{"now": seconds}``."""
    return "event: clock\ndata: {{\"now\":{}}}\n\n".format(robot_clock())


def format_event(kind, data):
    """One SSE event: ``event: kind`` and ``data: {json}`` (JSON has no newline: one data line)."""
    return "event: {}\ndata: {}\n\n".format(kind, json.dumps(data, separators=(",", ":"), default=str))
