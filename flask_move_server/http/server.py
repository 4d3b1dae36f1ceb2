"""The HTTP server: waitress, hardened for a robot anyone on the Wi-Fi can reach.

Waitress as it comes lets ~100 idle sockets lock every client out (it stops
accepting at ``connection_limit``), answers its own errors (400, 413, 431, 501)
in ``text/plain``, refuses a body of exactly the limit, and logs one warning
per queued request. This module builds the server from ``ServerConfig`` with a
connection policy: always accept; over ``connection_limit``, close the
connections that have waited longest without a request in progress (idle, or a
slow-loris still sending its headers), then busy ones from the address holding
the most (a pipelining flood; never a connection's first request); close a connection that has not
delivered a whole request within ``request_timeout`` and a keep-alive one idle
for ``channel_timeout``. One connection is ``http.connection`` (its timeouts,
bounded streams, JSON errors); who serves each request is ``http.lanes`` (the
stop lane, the stream lane, the queue summary).
"""

import collections
import ipaddress
import logging
import resource
import time

from waitress.adjustments import Adjustments
from waitress.server import TcpWSGIServer

from flask_move_server.http.connection import RobotChannel
from flask_move_server.http.lanes import QueueDepthSummary, StopLaneDispatcher

log = logging.getLogger(__name__)

QUEUE_LOGGER = "waitress.queue"
MAINTENANCE_INTERVAL = 1  # seconds between sweeps for timed-out connections
ACCEPT_BATCH = 64  # connections accepted in one pass of the loop, at most
ACCEPT_GRACE = 0.5  # seconds a just-accepted connection is never the one closed to make room


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
        # Keep accepting past the limit (room is made in handle_accept), up to a hard ceiling;
        # at the ceiling, room is made on every pass, not only once a second.
        if len(self.active_channels) < 2 * self.adj.connection_limit:
            return self.accepting
        self.make_room()
        return False

    def handle_accept(self):
        """Accept what waits, up to ``ACCEPT_BATCH`` connections a pass (waitress: one), making room.

        One a pass left the owner's connection behind every reconnect of a flood in the listen
        backlog, one loop pass each: seconds before its ``/stop`` was even read.
        """
        ceiling = 2 * self.adj.connection_limit
        for _ in range(ACCEPT_BATCH):
            before = len(self.active_channels)
            super().handle_accept()
            if len(self.active_channels) == before:
                return  # nothing waits (or the client left before it was accepted)
            self.make_room()
            if len(self.active_channels) >= ceiling:
                return

    def over_address_share(self, channel):
        """True when ``channel``'s address already holds ``connections_per_address`` others.

        One machine on the Wi-Fi opening hundreds of connections, each pipelining requests, made
        the loop parse thousands of them before it reached the owner's ``/stop``; the share keeps
        one address to a browser's worth and then some. This machine's addresses are not counted.
        """
        host = _host(channel)
        if host is None or _loopback(host):
            return False
        same = sum(1 for c in self.active_channels.values() if c is not channel and c.addr and c.addr[0] == host)
        return same >= self.policy.per_address

    def make_room(self):
        """Over ``connection_limit``: close the connections that have waited longest for nothing.

        Those lingering after a refusal go first (their answer is sent), so a burst of refused
        requests cannot fill the server; then those waiting longest on their client (idle, slow,
        or leaving their answers unread), never one accepted in the last ``ACCEPT_GRACE`` seconds
        (it would be the newcomer the room is made for). Closed as waitress closes, by the loop's next pass
        (closing a socket while the loop gathers its poll() lists would hand poll() a
        closed descriptor): ``will_close``, or a lingering channel's ``stop_lingering()``.
        """
        channels = list(self.active_channels.values())
        closing = sum(1 for c in channels if c.will_close and not c.lingering())
        excess = len(channels) - closing - self.adj.connection_limit
        if excess <= 0:
            return
        lingering = [c for c in channels if c.lingering()][:excess]
        for channel in lingering:
            channel.stop_lingering()
        newest = time.time() - ACCEPT_GRACE  # a connection this young has not had the time to ask
        open_ = [c for c in channels if not c.will_close and not c.lingering()]
        waiting = sorted((c.waiting_since(), id(c), c) for c in open_
                         if c.creation_time < newest and c.waiting_since() is not None)
        victims = [channel for _, _, channel in waiting[:excess - len(lingering)]]
        victims += self.busiest(open_, excess - len(lingering) - len(victims))
        self.close_soon(victims)
        self.policy.shed += len(lingering) + len(victims)

    @staticmethod
    def busiest(channels, count):
        """Up to ``count`` of ``channels`` with a request in service that had an answer before,
        from the addresses holding most.

        Connections that keep pipelining are never idle, so without this, a few hundred of them held
        every place and the owner's ``/stop`` was never accepted. A connection's first request is
        never cut (it may be the owner's); the address with the most connections gives first, its
        oldest first: the owner's phone holds a few, a flood many.
        """
        if count <= 0:
            return []
        busy = [c for c in channels if c.waiting_since() is None and c.requests_parsed > 1]
        held = collections.Counter(_host(c) for c in busy)
        busy.sort(key=lambda c: (-held[_host(c)], c.creation_time))
        return busy[:count]

    def maintenance(self, now):
        """Close connections past their timeouts; over the limit, make room again (once a second).

        Room is also made here, not only when a connection is accepted: at the hard ceiling the
        server accepts nothing, so connections past their grace, or whose client stopped reading
        since, would otherwise hold every place until their timeouts.
        """
        self.close_soon([channel for channel in list(self.active_channels.values()) if channel.overdue(now)])
        self.make_room()

    def close_soon(self, channels):
        """Close ``channels`` at the loop's next pass, as waitress closes (``will_close``).

        One whose client reads nothing never becomes writable, so waitress would never get to
        close it: those are closed from the loop's trigger, after its poll, never while the loop
        gathers what to poll (a descriptor closed then would be handed to poll()).
        """
        stalled = []
        for channel in channels:
            channel.will_close = True
            if channel.total_outbufs_len:
                stalled.append(channel)
        if stalled:
            self.trigger.pull_trigger(lambda: [c.handle_close() for c in stalled if c.connected])


class ConnectionPolicy:
    """The timeouts and counters the server's connection policy uses."""

    def __init__(self, server_config):
        self.request_timeout = server_config.request_timeout
        self.channel_timeout = server_config.channel_timeout
        self.per_address = server_config.connections_per_address
        self.shed = 0
        self.refused_addresses = 0


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
        """End :meth:`run` from another thread (tests, embedding): close from inside the loop, drain.

        Should the loop's wake-up pipe be gone already (seen once in `make test-debian`: EBADF from
        waitress's trigger at a test's teardown), the server is closed from here instead of raising.
        """
        if not self._closed:
            try:
                self._servers[0].trigger.pull_trigger(self.close)
            except OSError as exc:
                log.warning("could not wake the HTTP loop to stop it (%s): closing from this thread", exc)
                self.close()
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
        # poll(), not select(): select() cannot watch a descriptor numbered 1024 or more, and one
        # such connection (a large connection_limit, or ROS's own sockets and files) killed the loop
        asyncore_use_poll=True,
    )


def _host(channel):
    return channel.addr[0] if isinstance(channel.addr, tuple) else None


def _loopback(host):
    try:
        return ipaddress.ip_address(host.split("%")[0]).is_loopback
    except ValueError:
        return False


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
