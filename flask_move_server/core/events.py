"""In-process events: what changed in the robot, for the page's stream and for other parts.

Parts publish ``(kind, data)``: ``pose``, ``status``, ``mode``, ``map``, ``waypoints``,
``estop``, ``plan``, ``scan``, ``battery`` (the kinds docs/api.md lists for ``GET /events``),
``data`` a JSON-ready dict.
An event carries the new *state*, never a delta, so a reader that missed one loses nothing
by reading the next: that is what lets every subscription keep only the newest event of each
kind. A slow page therefore holds at most one pending event per kind, never a growing queue.

Two ways to hear them:
- ``listen(kind, callback)``: called in the publisher's thread (keep it short; an exception
  is logged, not raised to the publisher). For parts reacting in-process (the waypoint store
  following the active map).
- ``subscribe()``: a :class:`Subscription` to read from another thread (the SSE stream),
  closed when the reader goes away.

Pure: imports neither rospy nor Flask.
"""

import itertools
import logging
import threading
from collections import OrderedDict

log = logging.getLogger(__name__)

class Subscription:
    """One reader's pending events: the newest of each kind, oldest kind first."""

    def __init__(self, bus, kinds):
        self._bus = bus
        self.kinds = frozenset(kinds) if kinds else None
        self._pending = OrderedDict()  # kind -> (seq, data)
        self._ready = threading.Condition()
        self.closed = False

    def wants(self, kind):
        return self.kinds is None or kind in self.kinds

    def offer(self, kind, seq, data):
        """Keep ``data`` as the newest ``kind`` event (replacing an unread older one)."""
        with self._ready:
            self._pending.pop(kind, None)
            self._pending[kind] = (seq, data)
            self._ready.notify()

    def next(self, timeout):
        """The oldest pending ``(kind, data)``, or None after ``timeout`` s or once closed."""
        with self._ready:
            if not self._pending and not self.closed:
                self._ready.wait(timeout)
            if self.closed or not self._pending:
                return None
            kind, (_seq, data) = self._pending.popitem(last=False)
            return kind, data

    def close(self):
        """Stop receiving; a reader waiting in ``next`` returns None at once. Idempotent."""
        with self._ready:
            self.closed = True
            self._pending.clear()
            self._ready.notify_all()
        self._bus._drop(self)


class EventBus:
    """Publish state changes to listeners and subscriptions, thread-safely."""

    def __init__(self):
        self._lock = threading.Lock()
        self._listeners = {}
        self._subscriptions = []
        self._latest = {}
        self._on_subscribe = []
        self._seq = itertools.count(1)
        self.closed = False

    def publish(self, kind, data):
        """Tell everyone that ``kind`` is now ``data``."""
        with self._lock:
            seq = next(self._seq)
            self._latest[kind] = data
            listeners = list(self._listeners.get(kind, ()))
            subscriptions = [s for s in self._subscriptions if s.wants(kind)]
        for sub in subscriptions:
            sub.offer(kind, seq, data)
        for callback in listeners:
            try:
                callback(data)
            except Exception:  # a listener's bug must not break the publisher (a ROS callback, a route)
                log.exception("event listener for %r failed", kind)

    def listen(self, kind, callback):
        """Call ``callback(data)`` on every ``kind`` event, in the publisher's thread."""
        with self._lock:
            self._listeners.setdefault(kind, []).append(callback)

    def when_subscribed(self, callback):
        """Call ``callback()`` in a new subscriber's thread, before it is primed: a part that tells its
        state only while someone reads (the reporter) brings it up to date there."""
        with self._lock:
            self._on_subscribe.append(callback)

    def subscribe(self, kinds=None, replay=True):
        """A new subscription to ``kinds`` (None: all); with ``replay``, primed with the latest of each."""
        sub = Subscription(self, kinds)
        with self._lock:
            sub.closed = self.closed  # the server is stopping: a late reader gets nothing more
            self._subscriptions.append(sub)
            hooks = list(self._on_subscribe)
        for callback in hooks:
            try:
                callback()
            except Exception:  # a part's bug must not cost the reader its stream
                log.exception("bringing events up to date for a new subscriber failed")
        if replay:
            with self._lock:
                latest = [(k, d) for k, d in self._latest.items() if sub.wants(k)]
                seq = next(self._seq)
            for kind, data in latest:  # the newest of each kind, even if a hook's event reached sub first
                sub.offer(kind, seq, data)
        return sub

    def latest(self, kind):
        """The last ``kind`` event's data, or None."""
        with self._lock:
            return self._latest.get(kind)

    @property
    def subscribers(self):
        with self._lock:
            return len(self._subscriptions)

    def _drop(self, sub):
        with self._lock:
            if sub in self._subscriptions:
                self._subscriptions.remove(sub)

    def close(self):
        """Close every subscription (the server is stopping), and any made later. Idempotent."""
        with self._lock:
            self.closed = True
            subscriptions = list(self._subscriptions)
        for sub in subscriptions:
            sub.close()
