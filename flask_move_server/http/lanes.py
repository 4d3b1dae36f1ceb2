"""Who serves a request: waitress's worker threads, with a stop lane and a stream lane.

- a stop lane: ``POST /stop`` (and ``/estop``) jumps the request queue, and gets a spare thread
  when every worker is busy (a ``/goto`` with ``wait`` holds one), so the owner can always stop
  the robot;
- a stream lane: each ``GET /events`` stream is served on a thread of its own (at most
  ``server.max_streams``), never on one of the ``server.threads`` workers, so open pages never
  delay ``/stop`` or anything else;
- a rate-limited summary instead of waitress's ``Task queue depth`` line per queued request.
"""

import threading
import time

from waitress.task import ThreadedTaskDispatcher

URGENT = frozenset({("POST", "/stop"), ("POST", "/estop")})
STREAMS = frozenset({("GET", "/events")})
SPARE_THREADS = 2  # extra threads the stop lane may start when every worker is busy
QUEUE_SUMMARY_INTERVAL = 60.0


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
            thread = threading.Thread(target=self._serve, args=(task, self._stream_ended), name="waitress-event-stream",
                                      daemon=True)
            with self.lock:
                self._stream_threads.add(thread)
            thread.start()
            return
        if line not in URGENT:
            others_busy = self.active_count > 1  # besides the worker that may still be finishing this client's last
            super().add_task(task)  # a stream past max_streams too: the app answers it 503 at once
            if others_busy:
                _hand_over_gil()
            return
        with self.lock:
            idle = len(self.threads) - self.stop_count - self.active_count
            queued = idle > len(self.queue) or not self._spares.acquire(blocking=False)
            if queued:
                self.queue.appendleft(task)
                self.queue_cv.notify()
        if queued:
            _hand_over_gil()
            return
        threading.Thread(target=self._serve, args=(task, self._spares.release), name="waitress-stop-lane",
                         daemon=True).start()

    def _serve(self, task, release):
        """Serve ``task`` on this thread of its own, then give its lane's place back with ``release()``."""
        try:
            task.service()
        except BaseException:
            self.logger.exception("Exception when servicing %r", task)
        finally:
            release()

    def _stream_ended(self):
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


def _hand_over_gil():
    """Let the worker just woken for a task take the GIL now, not after the loop's whole pass.

    The event loop is one thread: a worker it wakes needs the GIL, which the loop keeps while it
    reads and parses the next connections, until Python's switch interval (5 ms) forces it off.
    Under concurrent clients every request paid that wait, and throughput fell to 0.2-0.7 of one
    client's (bench_concurrency, issue 32). Waitress as it came happened to hand the GIL over here
    whenever workers were busy, by logging its "Task queue depth" line to stderr from this spot;
    counting that line instead (6d0c33d) took the hand-over away. Only while other workers are
    busy: with one client a hand-over is two context switches for nothing (the loop releases the
    GIL in its poll() right after), which cost ~0.2 ms of CPU a request. ``time.sleep(0)`` releases
    the GIL, nothing else.
    """
    time.sleep(0)


def _request_line(channel):
    requests = getattr(channel, "requests", None)
    if not requests:
        return None
    request = requests[0]
    return getattr(request, "command", None), getattr(request, "path", None)


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
