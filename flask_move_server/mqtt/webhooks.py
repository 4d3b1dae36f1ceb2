"""Webhooks: a JSON POST to the owner's URL on each happening it lists, for owners without MQTT.

Each happening (happenings.py) a webhook lists becomes ``{"event", "robot", "at", ...data}``
POSTed to its URL (docs/webhooks.md shows each body). Each webhook has its own worker thread and
bounded queue, so the robot never waits on a receiver and one slow receiver never delays another:
the happening's thread only queues (when a queue is full the newest is dropped, counted, with a
warning now and then). Each try is at most ``timeout`` s in all, connect to answer, and the
answer's body is never read (``webhook_post.py``); a connection error, a timeout, a 5xx or a 429
is tried again after ``backoff`` (1 s, then 2 s: three tries in all); any other answer but 2xx is
final. Redirects are not followed. With a ``secret`` the body is signed (``X-Robot-Signature-256:
sha256=<HMAC-SHA256 of the body>``), so a receiver can tell the robot's calls from forged ones. No
Authorization header is ever sent (the server's token stays on the robot), nor credentials from
``~/.netrc`` or a proxy from the environment. A URL's path is often its secret (Home Assistant's):
the log names only its scheme and host.
"""

import http.client
import json
import logging
import queue
import threading
import time
from urllib.parse import urlsplit

from flask_move_server import __version__
from flask_move_server.config import rules
from flask_move_server.core.errors import ConfigError
from flask_move_server.core.happenings import utc_now_iso
from flask_move_server.mqtt import webhook_post
from flask_move_server.process.log_limits import Throttled

log = logging.getLogger(__name__)

USER_AGENT = "flask-move-server/{} (webhooks)".format(__version__)
TIMEOUT = 5.0  # s per try, connect to answer
BACKOFF = (1.0, 2.0)  # s before the second and the third try
QUEUE = 100  # POSTs waiting for one receiver; more are dropped
CLOSE_WAIT = 2.0  # s close() gives what is queued (one try each); a POST under way is then left to its timeout
POLL = 0.2  # s a worker waits for more once closing, before it ends
MAX_SECRET = 1024  # bytes of a webhook's secret


class _Receiver:
    """One webhook: its URL, the events it lists, its secret (bytes or None), its queue and its worker."""

    def __init__(self, url, events, secret, queue_size):
        self.url, self.events, self.secret = url, events, secret
        self.queue = queue.Queue(maxsize=queue_size)
        self.worker = None


class Webhooks:
    """POSTs happenings to the URLs of ``hooks`` (config.WebhookConfig items) as robot ``robot_name``."""

    def __init__(self, hooks, robot_name, happenings, timeout=TIMEOUT, backoff=BACKOFF, queue_size=QUEUE,
                 close_wait=CLOSE_WAIT, clock=utc_now_iso):
        self._receivers = [_Receiver(hook.url, frozenset(hook.events), _secret(hook, index), queue_size)
                           for index, hook in enumerate(_checked(hooks))]
        self._robot = robot_name
        self._timeout = timeout
        self._backoff = tuple(backoff)
        self._close_wait = close_wait
        self._clock = clock
        self._stopping = threading.Event()
        self._deadline = None  # monotonic time the workers stop sending, once closing
        self._lock = threading.Lock()
        self._counts = {"sent": 0, "failed": 0, "dropped": 0}
        self._drops = Throttled(log, "webhook drop warnings", burst=1, interval=60.0)
        self._failures = Throttled(log, "webhook failure warnings", burst=5, interval=60.0)
        for receiver in self._receivers:
            receiver.worker = threading.Thread(target=self._work, args=(receiver,), name="webhooks", daemon=True)
            receiver.worker.start()
        happenings.listen(self._happened)
        log.info("webhooks: %s", "; ".join("{} on {}{}".format(_where(r.url), ", ".join(sorted(r.events)),
                                                                 ", signed" if r.secret else "")
                                            for r in self._receivers))

    def status(self):
        """``{"sent", "failed", "dropped", "queued"}``: POSTs delivered, given up, dropped (queue full), waiting."""
        with self._lock:
            counts = dict(self._counts)
        counts["queued"] = sum(r.queue.qsize() for r in self._receivers)
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
        for receiver in self._receivers:
            try:
                receiver.queue.put_nowait(None)  # wakes a worker waiting for work
            except queue.Full:
                pass  # the worker is busy: it sees _stopping before the next POST
        for receiver in self._receivers:
            receiver.worker.join(max(0.0, self._deadline - time.monotonic()))
        unsent = sum(_empty(r.queue) for r in self._receivers)
        busy = any(r.worker.is_alive() for r in self._receivers)
        counts = self.status()
        log.info("webhooks: %d sent, %d failed, %d dropped%s%s", counts["sent"], counts["failed"], counts["dropped"],
                 ", {} not sent (the server stopped)".format(unsent) if unsent else "",
                 "; a POST still under way is left to its timeout" if busy else "")

    # the happening's thread: queue only --------------------------------------------------------

    def _happened(self, name, data):
        if self._stopping.is_set():
            return
        body = {"event": name, "robot": self._robot, "at": self._clock()}
        for key, value in data.items():
            body.setdefault(key, value)
        for receiver in self._receivers:
            if name not in receiver.events:
                continue
            try:
                receiver.queue.put_nowait(body)
            except queue.Full:
                with self._lock:
                    self._counts["dropped"] += 1
                    dropped = self._counts["dropped"]
                self._drops.log(logging.WARNING, "webhooks: %d POSTs already waiting (a receiver is slow or down): "
                                "%s to %s dropped, %d dropped so far", receiver.queue.maxsize, name,
                                _where(receiver.url), dropped)

    # a receiver's worker -------------------------------------------------------------------------

    def _work(self, receiver):
        while True:
            try:
                body = receiver.queue.get(timeout=POLL if self._stopping.is_set() else None)
            except queue.Empty:
                return  # closing, and nothing more queued
            if body is None or (self._stopping.is_set() and time.monotonic() >= self._deadline):
                return
            self._deliver(receiver, body)

    def _deliver(self, receiver, body):
        """POST ``body`` to the receiver, tried again after each back-off while it may help."""
        data = json.dumps(body).encode("utf-8")
        headers = {"Content-Type": "application/json", "User-Agent": USER_AGENT}
        if receiver.secret is not None:
            headers[webhook_post.SIGNATURE_HEADER] = webhook_post.signature(receiver.secret, data)
        tries = len(self._backoff) + 1
        for attempt in range(tries):
            if attempt and self._stopping.wait(self._backoff[attempt - 1]):
                break  # the server is stopping: no more tries
            problem, again = self._post(receiver.url, data, headers)
            if problem is None:
                with self._lock:
                    self._counts["sent"] += 1
                return
            if not again:
                break
        with self._lock:
            self._counts["failed"] += 1
        self._failures.log(logging.WARNING, "webhooks: %s to %s not delivered (%d %s): %s", body["event"],
                           _where(receiver.url), attempt + 1, "try" if attempt == 0 else "tries", problem)

    def _post(self, url, data, headers):
        """One try: ``(None, False)`` when delivered, else ``(problem, worth trying again)``. The problem never
        names the URL's path."""
        try:
            code = webhook_post.post(url, data, headers, self._timeout)
        except webhook_post.RanOver as exc:
            return str(exc), True
        except (OSError, ValueError, http.client.HTTPException) as exc:  # refused, reset, not an HTTP answer
            return _problem(exc), True
        if 200 <= code < 300:
            return None, False
        if 300 <= code < 400:
            return "HTTP {}: a redirect, not followed (give the final URL)".format(code), False
        return "HTTP {}".format(code), code >= 500 or code == 429


def _problem(exc):
    """What went wrong, without the exception's text where it may quote the URL (whose path is a secret)."""
    if isinstance(exc, OSError) and exc.strerror:
        return "{}: {}".format(type(exc).__name__, exc.strerror)
    return type(exc).__name__


def _checked(hooks):
    for index, hook in enumerate(hooks):
        problem = rules.web_url(hook.url or "")
        if problem:
            raise ConfigError("config", "webhooks[{}].url".format(index), "{} (got {!r})".format(problem, hook.url))
    return hooks


def _secret(hook, index):
    """The webhook's secret as bytes (from ``secret``, or the first line of ``secret_file``), or None."""
    where = "webhooks[{}]".format(index)
    if hook.secret is not None and hook.secret_file is not None:
        raise ConfigError("config", where, "give secret or secret_file, not both")
    text = hook.secret
    if hook.secret_file is not None:
        try:
            with open(hook.secret_file, encoding="utf-8") as f:
                text = f.readline().rstrip("\r\n")
        except OSError as exc:
            raise ConfigError(hook.secret_file, where + ".secret_file", "cannot read the webhook's secret: {}".format(
                exc.strerror or exc))
    if text is None:
        return None
    secret = text.encode("utf-8")
    if not 1 <= len(secret) <= MAX_SECRET:
        raise ConfigError("config", where + ".secret", "must be 1 to {} bytes".format(MAX_SECRET))
    return secret


def _empty(waiting):
    """What was left queued (the worker has stopped sending), thrown away: how many POSTs."""
    unsent = 0
    while True:
        try:
            item = waiting.get_nowait()
        except queue.Empty:
            return unsent
        unsent += item is not None


def _where(url):
    """``http://host:port`` of ``url``: a Home Assistant webhook's path is its secret, kept out of the log."""
    parts = urlsplit(url)
    return "{}://{}".format(parts.scheme, parts.netloc)
