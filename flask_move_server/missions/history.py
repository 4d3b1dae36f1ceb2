"""The runs kept across restarts: ``runs.json`` in the state folder, the newest 50.

Every change of a run is written (by a :class:`~flask_move_server.core.state_writer.StateWriter`,
atomically, never in the caller's thread). A run still ``running`` or ``paused`` in the file at
start was cut short by a stop of the server (SIGTERM, a crash, a power cut): it is
``interrupted``, and stays so until someone resumes it; the robot never drives off by itself
after a restart. A file that cannot be read is renamed aside (``runs.json.broken-<time>``) with one
warning, and the runs start afresh; a run in it that does not pass the API's checks (a hand edit:
``"dwell": 1e308``) sets the file aside the same way, and the other runs are kept.
Not thread-safe: the executor calls it under its own lock. Pure: no rospy, no Flask.
"""

import json
import logging
import os
import time

from flask_move_server.core.state_writer import StateWriter
from flask_move_server.missions.run import CANCELED, FAILED, INTERRUPTED, SKIPPED, SUCCEEDED, Run
from flask_move_server.waypoints import locked_file

log = logging.getLogger(__name__)

KEPT = 50
SAVE_WAIT = 2.0  # s a new run's answer waits for it to be on disk (an SD card's fsync: tens of ms)
PROGRESS_WRITES = 10.0  # s: a run's progress (a waypoint reached) is written at most this often; states at once
ENDED = (SUCCEEDED, FAILED, CANCELED, SKIPPED)  # a run in one of these never changes again
CUT_SHORT = "The server stopped while this run was under way (at {}, loop {}); resume it to go on from there."


class RunHistory:
    """The newest :data:`KEPT` runs, newest first, kept in ``path``."""

    def __init__(self, path, keep=KEPT):
        self.path = path
        self.keep = keep
        self._rewrite = False  # runs were dropped on loading: the file is written again at once
        self._runs = self._load()
        self._texts = {}  # run id -> its JSON, for the ended runs (each made once, not at every change)
        self.next_id = max((r.id for r in self._runs), default=0) + 1
        self._writer = StateWriter(path, "the runs", "run-history", min_interval=PROGRESS_WRITES)
        if self._rewrite or any(r.state == INTERRUPTED for r in self._runs):
            self.changed()

    def _load(self):
        """The kept runs; a file that cannot be read, or holds a run that does not pass the API's checks, is
        renamed aside (``runs.json.broken-<time>``) and said once, and the runs that pass are kept."""
        try:
            text = locked_file.read(self.path)  # bounded: a hand-made file cannot be huge
            items = json.loads(text or "[]")
            if not isinstance(items, list):
                raise ValueError("not a list of runs")
        except (OSError, ValueError, RecursionError) as exc:
            self._set_aside("cannot be read ({})".format(exc), "starting a new list")
            return []
        runs, bad = [], []
        for i, item in enumerate(items[:self.keep]):
            try:
                runs.append(Run.from_dict(item))
            except (ValueError, TypeError, KeyError, AttributeError) as exc:
                bad.append("entry {}: {}".format(i + 1, exc))
        if bad:
            self._set_aside("holds {} run{} that cannot be taken ({})".format(
                len(bad), "s" if len(bad) > 1 else "", "; ".join(bad[:3])), "keeping the other {}".format(len(runs)))
        for run in runs:
            if run.active:
                run.end(INTERRUPTED, CUT_SHORT.format(run.target, run.loop))
                run.ended = None  # interrupted, not over: it can be resumed
        self._rewrite = bool(bad)
        return runs

    def _set_aside(self, problem, then):
        """Rename the file aside, so the next write keeps what it held for its owner; one warning."""
        aside = "{}.broken-{}".format(self.path, time.strftime("%Y%m%d-%H%M%S"))
        try:
            os.replace(self.path, aside)
        except OSError as exc:
            log.warning("the runs kept in %s %s, and it cannot be set aside (%s): %s; the next change "
                        "overwrites it", self.path, problem, exc.strerror or exc, then)
            return
        log.warning("the runs kept in %s %s: set aside as %s (nothing is lost), %s", self.path, problem, aside, then)

    def add(self, run):
        """Keep ``run`` as the newest; the oldest beyond :attr:`keep` goes."""
        self._runs.insert(0, run)
        del self._runs[self.keep:]
        self._texts = {r.id: self._texts[r.id] for r in self._runs if r.id in self._texts}
        self.next_id = max(self.next_id, run.id + 1)
        return self.changed()

    def changed(self, progress=False):
        """A kept run changed: write the list soon (the same text as ``json.dumps`` of the list).

        ``progress``: only where a run is (a waypoint reached, the next one chosen), written within
        :data:`PROGRESS_WRITES` s; a crash meanwhile resumes the run a waypoint or two early.
        """
        return self._writer.write("[" + ", ".join(self._text(r) for r in self._runs) + "]\n", urgent=not progress)

    def saved(self, ticket, timeout=SAVE_WAIT):
        """Wait (at most ``timeout`` s) until the change of ``ticket`` is on disk: True when it is."""
        return self._writer.written(ticket, timeout)

    def _text(self, run):
        """``run`` as JSON: an ended run's is made once (50 patrols of 100 visits: ~10 ms each time)."""
        text = self._texts.get(run.id)
        if text is None:
            text = json.dumps(run.as_dict(), ensure_ascii=False)
            if run.state in ENDED:
                self._texts[run.id] = text
        return text

    def all(self):
        return list(self._runs)

    def get(self, run_id):
        return next((r for r in self._runs if r.id == run_id), None)

    def close(self):
        self._writer.close()


def default_path(state_folder):
    return os.path.join(state_folder, "runs.json")
