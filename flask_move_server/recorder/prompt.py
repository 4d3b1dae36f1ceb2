"""The recorder's terminal loop: lines typed, RViz clicks, and a safe Ctrl-C.

Every save runs with SIGINT deferred: a Ctrl-C that lands mid-save takes
effect right after it, so the waypoints file (or the server) always holds
every change the recorder reported, whole.
"""

import contextlib
import os
import select
import signal
import threading
import time

from flask_move_server.core.errors import MoveServerError


@contextlib.contextmanager
def interrupts_deferred():
    """Hold back Ctrl-C (SIGINT) and SIGTERM until the block is done, then raise KeyboardInterrupt."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught = []
    signals = (signal.SIGINT, signal.SIGTERM)
    previous = [signal.signal(signum, lambda signum, frame: caught.append(signum)) for signum in signals]
    try:
        yield
    finally:
        for signum, handler in zip(signals, previous):
            signal.signal(signum, handler)
    if caught:
        raise KeyboardInterrupt


def run(session, fd, refresh_period=2.0, poll=0.1):
    """Feed ``session`` the lines read from ``fd`` and the queued clicks until it quits or input ends.

    With ``auto_names`` no line is needed: the end of input (roslaunch starts nodes with none)
    only stops reading it, and clicks are recorded until Ctrl-C or SIGTERM.
    """
    pending = b""
    refresher = _Refresher(session, refresh_period)
    while session.running:
        with interrupts_deferred():  # one save at a time, so Ctrl-C lands between saves
            more_clicks = session.handle_clicks(limit=1)
        with interrupts_deferred():
            refresher.maybe()
        if fd is None:
            time.sleep(0 if more_clicks else poll)
            continue
        ready, _, _ = select.select([fd], [], [], 0 if more_clicks else poll)
        if not ready:
            continue
        data = os.read(fd, 4096)
        if not data:  # end of input (Ctrl-D, a closed pipe, none at all)
            if not session.auto_names:
                return
            fd = None
            continue
        pending += data
        while b"\n" in pending and session.running:
            line, pending = pending.split(b"\n", 1)
            with interrupts_deferred():
                session.handle_line(line.decode("utf-8", "replace"))


class _Refresher:
    """Re-reads the saved waypoints now and then, so RViz shows others' edits too."""

    def __init__(self, session, period):
        self.session, self.period = session, period
        self.next_time = 0.0
        self.problem = None

    def maybe(self):
        now = time.monotonic()
        if now < self.next_time:
            return
        self.next_time = now + self.period
        try:
            self.session.refresh()
        except MoveServerError as exc:
            if str(exc) != self.problem:
                self.session.say("Cannot read the waypoints: {}".format(exc))
            self.problem = str(exc)
        else:
            self.problem = None
