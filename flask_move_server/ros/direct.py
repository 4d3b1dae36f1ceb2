"""Goals and cancels written to move_base from the request's own thread, never blocking it.

A rospy publisher made with a ``queue_size`` hands each message to a writer thread per
subscriber (rospy's ``QueuedConnection``). On a goal's way to move_base that handoff took about
0.1 ms of the 1.5–2 ms trip (``bench/bench_goals.py --stages``): the writer waits for the GIL
while the request thread goes on to log and answer. Writing from the request thread alone made it
worse: move_base's reader, woken on the same core, then waited behind the request thread. A
publisher made by :func:`direct_publisher` writes each message from the publishing thread when
the socket takes all of it at once (``MSG_DONTWAIT``: never a wait), then yields the CPU
(``sched_yield``) so the subscriber's reader runs. When the socket cannot take it (a
subscriber that stopped reading, a full buffer), the message, or the rest of it, goes to the
connection's writer thread, which sends it as rospy's does: in order, whole, with the oldest
dropped past ``queue_size``. So a wedged subscriber (a frozen ``rostopic echo``) never holds up
``/goto`` or ``/stop``. Sockets get ``TCP_NODELAY``: a goal is one small write, sent at once.

Every ``rospy.Publisher`` of a topic in one process shares its topic's connections, so the
direct publisher must exist before any other (actionlib's, made with ``queue_size=10``): later
publishers of the topic then share its direct connections.
"""

import collections
import os
import socket
import threading

import rospy
from rospy.topics import _PublisherImpl

_SEND_NOW = getattr(socket, "MSG_DONTWAIT", 0x40)


def direct_publisher(topic, data_class, queue_size):
    """A ``rospy.Publisher`` of ``topic`` whose connections are :class:`DirectConnection`\\ s."""
    publisher = rospy.Publisher(topic, data_class, queue_size=queue_size, tcp_nodelay=True)
    impl = publisher.impl
    if not isinstance(impl, _DirectPublisherImpl):
        impl.direct_queue_size = impl.queue_size or 0
        impl.queue_size = None  # rospy must not wrap the connections in its own queue
        impl.__class__ = _DirectPublisherImpl
    return publisher


class _DirectPublisherImpl(_PublisherImpl):
    """rospy's shared implementation of one topic's publishers, with direct connections."""

    direct_queue_size = 0

    def set_queue_size(self, queue_size):
        # A later Publisher of the topic (actionlib's) asks for rospy's queue: its bound, our connections.
        self.direct_queue_size = queue_size or 0

    def add_connection(self, c):
        if not isinstance(c, DirectConnection):
            c = DirectConnection(c, self.direct_queue_size)
        try:
            return not self.closed and super().add_connection(c)
        finally:
            if self.closed:  # closed before or as the subscriber connected: rospy would leave its socket open
                c.close()


class DirectConnection:
    """A subscriber's TCPROS connection, written at once when it can be, else by its writer thread.

    Behaves towards rospy as its ``QueuedConnection`` does (the transport's attributes, an error of
    the writer raised by the next write). ``queue_size``: messages waiting for the writer at most
    (0: no bound); past it the oldest waiting whole message is dropped. The writer thread is started
    by the first message that has to wait and ends when the connection closes: a subscriber that
    always keeps up costs no thread.
    """

    def __init__(self, connection, queue_size):
        self._connection = connection
        self._queue_size = queue_size
        self._lock = threading.Lock()
        self._wake = threading.Condition(self._lock)
        self._waiting = collections.deque()
        self._writing = False  # the writer is sending a message outside the lock
        self._head_started = False  # the first waiting message is the rest of one partly sent: never dropped
        self._error = None
        self._writer = None  # started by the first message that has to wait for it
        connection.set_cleanup_callback(self._closed)

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        return getattr(self._connection, name)

    def write_data(self, data):
        with self._lock:
            if self._error is not None:
                error, self._error = self._error, None
                raise error
            rest = self._send_now(data) if not self._waiting and not self._writing else data
            if rest:
                self._wait_for_writer(rest)
        if not rest:
            os.sched_yield()  # let the subscriber's reader, just woken, have this core
        return True

    def _send_now(self, data):
        """Whatever of ``data`` the socket did not take at once (lock held)."""
        sock = self._connection.socket
        if sock is None or self._connection.done:
            return data  # the writer's write_data reports it as rospy does
        try:
            sent = sock.send(data, _SEND_NOW)
        except (BlockingIOError, InterruptedError):
            return data
        except OSError:
            return data  # the writer's write_data closes the connection and reports it
        self._connection.stat_bytes += sent
        if sent == len(data):
            self._connection.stat_num_msg += 1
            return b""
        self._head_started = sent > 0
        return data[sent:]

    def _wait_for_writer(self, data):
        """Queue ``data`` for the writer thread (lock held), dropping the oldest whole message past the bound."""
        if self._queue_size and len(self._waiting) >= self._queue_size:
            oldest_whole = 1 if self._head_started else 0
            if len(self._waiting) > oldest_whole:
                del self._waiting[oldest_whole]
        self._waiting.append(data)
        if self._writer is None:
            self._writer = threading.Thread(target=self._run, name="direct-writer", daemon=True)
            self._writer.start()
        self._wake.notify()

    def _closed(self, _connection):
        with self._lock:
            self._wake.notify()

    def _run(self):
        connection = self._connection
        while True:
            with self._lock:
                while not self._waiting and not connection.done:
                    self._wake.wait()
                if connection.done:
                    return
                data = self._waiting.popleft()
                self._head_started = False
                self._writing = True
            try:
                connection.write_data(data)
            except Exception as exc:  # as rospy's QueuedConnection: the next write raises it
                with self._lock:
                    self._error = exc
            finally:
                with self._lock:
                    self._writing = False
