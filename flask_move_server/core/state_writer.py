"""A small state file written by a thread of its own: only the newest wish reaches the disk.

The trip under way (``trip.json``) and the runs (``runs.json``) change while the robot is being
commanded; an SD card's fsync can take tens of milliseconds, and a request or the run executor
must never wait for one. :class:`StateWriter` takes the newest text (or a removal) and writes it
atomically (the waypoints file's plumbing) from its thread; a wish replaced before it was written
is never written. A crash loses at most the last moment's note, never a command. Wishes that are
not urgent (a run's progress) are written at most once per ``min_interval``: a patrol must not
rewrite the file twice a waypoint for months on an SD card. Pure: no rospy.
"""

import logging
import math
import os
import threading
import time

from flask_move_server.core.errors import WaypointFileError
from flask_move_server.waypoints import locked_file

log = logging.getLogger(__name__)


class StateWriter:
    """``write(text)`` / ``remove()`` ``path`` soon, newest first; ``close()`` writes what is pending."""

    def __init__(self, path, what, thread_name, min_interval=0.0):
        self.path = path
        self._what = what  # for the log: "the trip under way"
        self.min_interval = min_interval  # s between writes of wishes that are not urgent (an SD card's wear)
        self._cond = threading.Condition()
        self._wish = None  # ("write", text) or ("remove", None): the newest state to put on disk
        self._urgent = False
        self._last = -math.inf  # time.monotonic() of the last write
        self._asked = 0  # wishes taken so far: each write's ticket
        self._done = 0  # the ticket of the newest wish on disk (a newer one covers every older)
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=thread_name, daemon=True)
        self._thread.start()

    def write(self, text, urgent=True):
        """Put ``text`` on disk soon; not ``urgent``: at most once per :attr:`min_interval`, the newest then.
        Returns its ticket, for :meth:`written`."""
        return self._want("write", text, urgent)

    def remove(self):
        return self._want("remove", None, True)

    def _want(self, what, text, urgent):
        with self._cond:
            self._asked += 1
            self._wish = (what, text, self._asked)
            self._urgent = self._urgent or urgent
            self._cond.notify_all()
            return self._asked

    def written(self, ticket, timeout):
        """Wait up to ``timeout`` s until the wish of ``ticket`` (or a newer one) is on disk; True when it is.

        For what is acknowledged to a user (a run started): the answer comes after the fsync, so a
        crash right after it cannot lose it; anything else is never waited for."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._done < ticket and not self._closed:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(left)
            return self._done >= ticket

    def _run(self):
        while True:
            with self._cond:
                wish = self._next_wish()
            if wish is None:
                return
            what, text, ticket = wish
            self._apply(what, text)
            self._last = time.monotonic()
            with self._cond:
                self._done = ticket
                self._cond.notify_all()

    def _next_wish(self):
        """Lock held: the next wish to write (urgent: at once; else once ``min_interval`` passed); None once closed."""
        while True:
            if self._wish is None:
                if self._closed:
                    return None
                self._cond.wait()
                continue
            hold = self._last + self.min_interval - time.monotonic()
            if self._urgent or self._closed or hold <= 0:
                wish, self._wish, self._urgent = self._wish, None, False
                return wish
            self._cond.wait(hold)

    def _apply(self, what, text):
        try:
            if what == "write":
                os.makedirs(os.path.dirname(os.path.abspath(self.path)), exist_ok=True)
                locked_file.atomic_write(self.path, text)
            elif os.path.exists(self.path):
                os.unlink(self.path)
        except (OSError, WaypointFileError) as exc:
            log.warning("could not keep %s in %s: %s", self._what, self.path, exc)

    def close(self):
        """Write what is pending, then stop the thread. Idempotent."""
        with self._cond:
            self._closed = True
            self._cond.notify()
        self._thread.join(5)
