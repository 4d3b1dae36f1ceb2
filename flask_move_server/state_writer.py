"""A small state file written by a thread of its own: only the newest wish reaches the disk.

The trip under way (``trip.json``) and the runs (``runs.json``) change while the robot is being
commanded; an SD card's fsync can take tens of milliseconds, and a request or the run executor
must never wait for one. :class:`StateWriter` takes the newest text (or a removal) and writes it
atomically (the waypoints file's plumbing) from its thread; a wish replaced before it was written
is never written. A crash loses at most the last moment's note, never a command. Pure: no rospy.
"""

import logging
import os
import threading

from flask_move_server.errors import WaypointFileError
from flask_move_server.waypoints import locked_file

log = logging.getLogger(__name__)


class StateWriter:
    """``write(text)`` / ``remove()`` ``path`` soon, newest first; ``close()`` writes what is pending."""

    def __init__(self, path, what, thread_name):
        self.path = path
        self._what = what  # for the log: "the trip under way"
        self._cond = threading.Condition()
        self._wish = None  # ("write", text) or ("remove", None): the newest state to put on disk
        self._closed = False
        self._thread = threading.Thread(target=self._run, name=thread_name, daemon=True)
        self._thread.start()

    def write(self, text):
        self._want("write", text)

    def remove(self):
        self._want("remove", None)

    def _want(self, what, text):
        with self._cond:
            self._wish = (what, text)
            self._cond.notify()

    def _run(self):
        while True:
            with self._cond:
                while self._wish is None and not self._closed:
                    self._cond.wait()
                wish, self._wish = self._wish, None
            if wish is None:
                return
            self._apply(*wish)

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
