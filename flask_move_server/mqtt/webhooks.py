"""Webhooks: a JSON POST to the owner's URL on each happening it lists, for owners without MQTT.

Each happening (happenings.py) a webhook lists becomes ``{"event", "robot", "at", ...data}``
POSTed to its URL (docs/webhooks.md shows each body). One worker thread sends them in order
from a bounded queue, so the robot never waits on a receiver: the happening's thread only
queues (when the queue is full the newest is dropped, counted, with a warning now and then).
Each POST has ``timeout`` s; a connection error, a timeout, a 5xx or a 429 is tried again after
``backoff`` (1 s, then 2 s: three tries in all); any other answer but 2xx is final. Redirects
are not followed. No Authorization header is ever sent (the server's token stays on the robot),
nor credentials from ``~/.netrc`` or a proxy from the environment (``trust_env`` off). Receivers
are on the owner's LAN; a slow one delays the others (one worker), each try at most ``timeout``.
"""

import json
import logging
import queue
import threading
import time
from urllib.parse import urlsplit

import requests

from flask_move_server import __version__
from flask_move_server.config import rules
from flask_move_server.core.errors import ConfigError
from flask_move_server.core.happenings import utc_now_iso
from flask_move_server.process.log_limits import Throttled

log = logging.getLogger(__name__)

USER_AGENT = "flask-move-server/{} (webhooks)".format(__version__)
TIMEOUT = 5.0  # s per try
BACKOFF = (1.0, 2.0)  # s before the second and the third try
QUEUE = 100  # POSTs waiting; more are dropped
CLOSE_WAIT = 2.0  # s close() gives what is queued (one try each); a POST under way is then left to its timeout
POLL = 0.2  # s the worker waits for more once closing, before it ends


class Webhooks:
    """POSTs happenings to the URLs of ``hooks`` (config.WebhookConfig items) as robot ``robot_name``."""

    def __init__(self, hooks, robot_name, happenings, timeout=TIMEOUT, backoff=BACKOFF, queue_size=QUEUE,
                 close_wait=CLOSE_WAIT, clock=utc_now_iso):
        self._hooks = []
        for index, hook in enumerate(hooks):
            problem = rules.web_url(hook.url or "")
            if problem:
                raise ConfigError("config", "webhooks[{}].url".format(index), "{} (got {!r})".format(problem, hook.url))
            self._hooks.append((hook.url, frozenset(hook.events)))
        self._robot = robot_name
        self._timeout = timeout
        self._backoff = tuple(backoff)
        self._close_wait = close_wait
        self._clock = clock
        self._queue = queue.Queue(maxsize=queue_size)
        self._stopping = threading.Event()
        self._deadline = None  # monotonic time the worker stops sending, once closing
        self._lock = threading.Lock()
        self._counts = {"sent": 0, "failed": 0, "dropped": 0}
        self._drops = Throttled(log, "webhook drop warnings", burst=1, interval=60.0)
        self._failures = Throttled(log, "webhook failure warnings", burst=5, interval=60.0)
        self._session = requests.Session()
        self._session.trust_env = False  # no ~/.netrc credentials, no proxy from the environment
        self._worker = threading.Thread(target=self._work, name="webhooks", daemon=True)
        self._worker.start()
        happenings.listen(self._happened)
        log.info("webhooks: %s", "; ".join("{} on {}".format(_where(url), ", ".join(sorted(events)))
                                            for url, events in self._hooks))

    def status(self):
        """``{"sent", "failed", "dropped", "queued"}``: POSTs delivered, given up, dropped (queue full), waiting."""
        with self._lock:
            counts = dict(self._counts)
        counts["queued"] = self._queue.qsize()
        return counts

    def close(self):
        """Stop: happenings from now on are not sent; what is queued gets one try each for at most
        ``close_wait`` s (the server's last words: an exploration canceled by the shutdown), the rest is
        not sent. Returns after ``close_wait`` s at most: a POST still under way is left to its timeout in
        the worker's daemon thread. Idempotent."""
        if self._stopping.is_set():
            return
        self._deadline = time.monotonic() + self._close_wait
        self._stopping.set()
        try:
            self._queue.put_nowait(None)  # wakes a worker waiting for work
        except queue.Full:
            pass  # the worker is busy: it sees _stopping before the next POST
        self._worker.join(self._close_wait)
        unsent = self._empty_queue()
        counts = self.status()
        log.info("webhooks: %d sent, %d failed, %d dropped%s%s", counts["sent"], counts["failed"], counts["dropped"],
                 ", {} not sent (the server stopped)".format(unsent) if unsent else "",
                 "; a POST still under way is left to its timeout" if self._worker.is_alive() else "")

    def _empty_queue(self):
        """What was left queued (the worker has stopped sending), thrown away: how many POSTs."""
        unsent = 0
        while True:
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                return unsent
            unsent += item is not None

    # the happening's thread: queue only --------------------------------------------------------

    def _happened(self, name, data):
        if self._stopping.is_set():
            return
        body = {"event": name, "robot": self._robot, "at": self._clock()}
        for key, value in data.items():
            body.setdefault(key, value)
        for url, events in self._hooks:
            if name not in events:
                continue
            try:
                self._queue.put_nowait((url, body))
            except queue.Full:
                with self._lock:
                    self._counts["dropped"] += 1
                    dropped = self._counts["dropped"]
                self._drops.log(logging.WARNING, "webhooks: %d POSTs already waiting (a receiver is slow or down): "
                                "%s to %s dropped, %d dropped so far", self._queue.maxsize, name, _where(url), dropped)

    # the worker --------------------------------------------------------------------------------

    def _work(self):
        try:
            while True:
                try:
                    item = self._queue.get(timeout=POLL if self._stopping.is_set() else None)
                except queue.Empty:
                    return  # closing, and nothing more queued
                if item is None or (self._stopping.is_set() and time.monotonic() >= self._deadline):
                    return
                self._deliver(*item)
        finally:
            self._session.close()

    def _deliver(self, url, body):
        """POST ``body`` to ``url``, tried again after each back-off while it may help."""
        data = json.dumps(body).encode("utf-8")
        headers = {"Content-Type": "application/json", "User-Agent": USER_AGENT}
        tries = len(self._backoff) + 1
        for attempt in range(tries):
            if attempt and self._stopping.wait(self._backoff[attempt - 1]):
                break  # the server is stopping: no more tries
            problem, again = self._post(url, data, headers)
            if problem is None:
                with self._lock:
                    self._counts["sent"] += 1
                return
            if not again:
                break
        with self._lock:
            self._counts["failed"] += 1
        self._failures.log(logging.WARNING, "webhooks: %s to %s not delivered (%d %s): %s", body["event"],
                           _where(url), attempt + 1, "try" if attempt == 0 else "tries", problem)

    def _post(self, url, data, headers):
        """One try: ``(None, False)`` when delivered, else ``(problem, worth trying again)``."""
        try:
            response = self._session.post(url, data=data, headers=headers, timeout=self._timeout,
                                          allow_redirects=False)
        except requests.Timeout:
            return "no answer within {:g} s".format(self._timeout), True
        except requests.RequestException as exc:
            return "{}: {}".format(type(exc).__name__, _without_path(str(exc), url)), True
        response.close()
        code = response.status_code
        if 200 <= code < 300:
            return None, False
        if 300 <= code < 400:
            return "HTTP {}: a redirect, not followed (give the final URL)".format(code), False
        return "HTTP {}".format(code), code >= 500 or code == 429


def _where(url):
    """``http://host:port`` of ``url``: a Home Assistant webhook's path is its secret, kept out of the log."""
    parts = urlsplit(url)
    return "{}://{}".format(parts.scheme, parts.netloc)


def _without_path(text, url):
    """``text`` (an exception's, which names the URL's path) with the path and query left out."""
    parts = urlsplit(url)
    secret = parts.path + ("?" + parts.query if parts.query else "")
    return text.replace(secret, "/...") if len(secret) > 1 else text
