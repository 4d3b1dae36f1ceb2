"""Log lines that can come in storms, throttled: the first few each interval, then one summary.

A goal storm (a script sending goals back to back) logged 180-300 lines a second, ~1 GB a day
on an SD card; actionlib's "already in the DONE state" errors come in the same storms. Each
stream keeps its first ``burst`` lines per ``interval`` and counts the rest; the next line after
the interval says how many were left out.
"""

import logging
import threading
import time


class Throttled:
    """Lines of one kind to ``logger``: at most ``burst`` per ``interval`` seconds, the rest counted."""

    def __init__(self, logger, what, burst=10, interval=10.0, clock=time.monotonic):
        self._logger = logger
        self._what = what
        self._burst = burst
        self._interval = interval
        self._clock = clock
        self._lock = threading.Lock()
        self._window = None
        self._shown = self._left_out = 0

    def log(self, level, msg, *args):
        """Log ``msg % args`` at ``level`` unless this interval's lines are spent (then count it)."""
        now = self._clock()
        with self._lock:
            if self._window is None or now - self._window >= self._interval:
                left_out, since = self._left_out, self._window
                self._window, self._shown, self._left_out = now, 0, 0
                if left_out:
                    self._logger.warning("%d more %s left out of the log in %.0f s", left_out, self._what,
                                         now - since)
            if self._shown >= self._burst:
                self._left_out += 1
                return
            self._shown += 1
        self._logger.log(level, msg, *args)

    def info(self, msg, *args):
        self.log(logging.INFO, msg, *args)


class ThrottleFilter(logging.Filter):
    """A logging filter throttling records whose message contains one of ``phrases`` (another
    library's lines, such as rospy's actionlib errors, that this code does not write itself)."""

    def __init__(self, phrases, burst=5, interval=60.0, clock=time.monotonic):
        super().__init__()
        self._phrases = tuple(phrases)
        self._burst, self._interval, self._clock = burst, interval, clock
        self._lock = threading.Lock()
        self._window = None
        self._shown = self._left_out = 0

    def filter(self, record):
        message = record.getMessage()
        if not any(phrase in message for phrase in self._phrases):
            return True
        now = self._clock()
        with self._lock:
            if self._window is None or now - self._window >= self._interval:
                if self._left_out:
                    record.msg, record.args = "{} ({} more like it left out of the log in {:.0f} s)".format(
                        message, self._left_out, now - self._window), ()
                self._window, self._shown, self._left_out = now, 0, 0
            if self._shown >= self._burst:
                self._left_out += 1
                return False
            self._shown += 1
            return True
