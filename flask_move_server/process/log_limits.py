"""Log lines that can come in storms, throttled: the first few each interval, then a count.

A goal storm (a script sending goals back to back) logged 180-300 lines a second, ~1 GB a day
on an SD card; actionlib's "already in the DONE state" errors come in the same storms. Each
stream keeps its first ``burst`` lines per ``interval`` and counts the rest; the next line after
the interval says how many were left out.
"""

import logging
import threading
import time


class _Window:
    """The counting both throttles share: ``burst`` lines per ``interval`` seconds, the rest counted."""

    def __init__(self, burst, interval, clock):
        self._burst, self._interval, self._clock = burst, interval, clock
        self._lock = threading.Lock()
        self._start = None
        self._shown = self._left_out = 0

    def admit(self):
        """(True when this line may be logged, (left out, seconds) of the window just ended or None)."""
        now = self._clock()
        with self._lock:
            ended = None
            if self._start is None or now - self._start >= self._interval:
                if self._left_out:
                    ended = (self._left_out, now - self._start)
                self._start, self._shown, self._left_out = now, 0, 0
            if self._shown >= self._burst:
                self._left_out += 1
                return False, ended
            self._shown += 1
            return True, ended


class Throttled:
    """Lines of one kind to ``logger``: at most ``burst`` per ``interval`` seconds, the rest counted."""

    def __init__(self, logger, what, burst=10, interval=10.0, clock=time.monotonic):
        self._logger = logger
        self._what = what
        self._window = _Window(burst, interval, clock)

    def log(self, level, msg, *args):
        """Log ``msg % args`` at ``level`` unless this interval's lines are spent (then count it)."""
        admitted, ended = self._window.admit()
        if ended:
            self._logger.warning("%d more %s left out of the log in %.0f s", ended[0], self._what, ended[1])
        if admitted:
            self._logger.log(level, msg, *args)

    def info(self, msg, *args):
        self.log(logging.INFO, msg, *args)


class ThrottleFilter(logging.Filter):
    """A logging filter throttling records whose message contains one of ``phrases`` (another
    library's lines, such as rospy's actionlib errors, that this code does not write itself)."""

    def __init__(self, phrases, burst=5, interval=60.0, clock=time.monotonic):
        super().__init__()
        self._phrases = tuple(phrases)
        self._window = _Window(burst, interval, clock)

    def filter(self, record):
        message = record.getMessage()
        if not any(phrase in message for phrase in self._phrases):
            return True
        admitted, ended = self._window.admit()
        if admitted and ended:
            record.msg, record.args = "{} ({} more like it left out of the log in {:.0f} s)".format(
                message, *ended), ()
        return admitted
