"""Starts routes at the times of their timetables: one thread that wakes just after each minute.

Each check asks for the active map's routes afresh and calls ``on_due(route)`` once for every route
with an entry in the minutes that began since the last check. Only minutes that really passed count:
a Raspberry Pi without a clock battery boots in 1970 or at its last shutdown and NTP then moves the
clock hours ahead, so the span checked is never longer than what the monotonic clock says passed.
Schedules missed while the server was down, or jumped over by the clock, are not run late; a minute a
route already ran in (a clock set back, the hour repeated when daylight saving ends) never runs it again.
:func:`due_routes` is the pure part; :class:`Scheduler` its thread.
"""

import logging
import math
import threading
import time
from datetime import datetime

from flask_move_server.core.errors import BadRoute
from flask_move_server.missions import schedule

log = logging.getLogger(__name__)

MINUTE = 60
WAKE_AFTER = 0.2  # s after a minute begins: the check then sees that minute, whatever the wait's jitter
SLACK = 2.0  # s the wall clock may run ahead of the monotonic one between checks without being a jump
START_AFRESH = 86400.0  # s: a clock set back further than this (an RTC that ran ahead) is not waited for


def minute_starts(start_epoch, end_epoch):
    """The epoch seconds at which each minute in (``start_epoch``, ``end_epoch``] begins, oldest first."""
    first = int(math.floor(start_epoch / MINUTE)) * MINUTE + MINUTE
    return range(first, int(math.floor(end_epoch)) + 1, MINUTE)


def minute_key(moment):
    """A local datetime's minute as ``'YYYY-MM-DD HH:MM'``: sorts in time order, the same in a repeated hour."""
    return "{:04d}-{:02d}-{:02d} {:02d}:{:02d}".format(moment.year, moment.month, moment.day, moment.hour,
                                                       moment.minute)


def due_routes(routes, start_epoch, end_epoch, local, fired):
    """The routes with a timetable entry in a minute beginning in (``start_epoch``, ``end_epoch``], once each.

    ``local(epoch)`` gives the robot's local datetime: a local time that does not exist that day
    (daylight saving starts) is never reached, so it matches nothing. ``fired`` maps a route name to
    the last local minute (:func:`minute_key`) it was started for, and is updated: a route is due only
    in a later local minute, so a repeated hour or a clock set back never starts it twice.
    """
    timetables = [(route, _slots(route)) for route in routes if route.schedule]
    due = {}
    for minute in minute_starts(start_epoch, end_epoch):
        moment = local(minute)
        key = minute_key(moment)
        for route, slots in timetables:
            if key > fired.get(route.name, "") and any(slot.matches(moment) for slot in slots):
                fired[route.name] = key
                due.setdefault(route.name, route)
    return list(due.values())


def _slots(route):
    """The route's timetable as :class:`~schedule.Slot` s; an entry that does not parse is logged and left out."""
    slots = []
    for entry in route.schedule:
        try:
            slots.append(schedule.parse(entry))
        except BadRoute as exc:
            log.warning("route %r: schedule entry %r is not run: %s", route.name, entry, exc)
    return slots


def jump_text(seconds):
    """A clock jump as a log shows it: ``+3h12m``, ``-1h00m``, ``+45s``."""
    sign = "-" if seconds < 0 else "+"
    seconds = abs(seconds)
    if seconds < MINUTE:
        return "{}{:.0f}s".format(sign, seconds)
    minutes = int(seconds // MINUTE)
    return "{}{}h{:02d}m".format(sign, minutes // 60, minutes % 60)


class Scheduler:
    """Calls ``on_due(route)`` from its thread when a route of ``routes()`` is due by its timetable.

    ``routes``: a callable giving the current routes (the active map's; asked afresh at every check).
    ``wall``, ``monotonic``, ``local``: the clocks, injectable for tests. An error from ``routes()``
    or ``on_due`` is logged and the schedules go on. ``start()`` starts the thread, ``close()`` stops
    and joins it (twice is fine); as a context manager it starts on entry and closes on exit.
    """

    def __init__(self, routes, on_due, wall=time.time, monotonic=time.monotonic, local=datetime.fromtimestamp):
        self._routes = routes
        self._on_due = on_due
        self._wall = wall
        self._monotonic = monotonic
        self._local = local
        self._fired = {}  # route name -> minute_key of its last start
        self._last_wall = wall()  # minutes up to here are checked: what was missed before is not run late
        self._last_mono = monotonic()
        self._closing = threading.Event()
        self._thread = threading.Thread(target=self._run, name="route-scheduler", daemon=True)
        self._started = False

    def start(self):
        """Start the thread (once; again does nothing). Minutes before now are not checked: no late runs."""
        if not self._started:
            self._started = True
            self._last_wall, self._last_mono = self._wall(), self._monotonic()
            self._thread.start()

    def close(self):
        """Stop the thread and wait for it, even while it sleeps until the next minute; idempotent."""
        self._closing.set()
        if self._started:
            self._thread.join(5)

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc):
        self.close()

    def check(self):
        """Start the routes due in the minutes that began since the last check (the thread's once-a-minute work)."""
        wall, mono = self._wall(), self._monotonic()
        start = self._span_start(wall, mono)
        self._last_mono = mono
        try:
            routes = list(self._routes())
        except Exception:
            log.exception("could not read the routes to check their schedules")
            return
        for route in due_routes(routes, start, wall, self._local, self._fired):
            self._start_run(route)

    def _span_start(self, wall, mono):
        """Where this check's span begins: no earlier than the last check, nor than the time that really passed."""
        passed = mono - self._last_mono
        afresh = self._last_wall - wall > START_AFRESH
        self._note_jump((wall - self._last_wall) - passed, afresh)
        if afresh:
            self._last_wall, self._fired = wall, {}
        start = max(self._last_wall, wall - passed - SLACK)
        self._last_wall = max(self._last_wall, wall)
        return start

    @staticmethod
    def _note_jump(jump, afresh):
        """One log line when the wall clock moved ``jump`` s more than the time that passed."""
        if jump > SLACK:
            log.info("the clock jumped by %s; schedules in between are not run", jump_text(jump))
        elif afresh:
            log.info("the clock jumped by %s; schedules start afresh from now", jump_text(jump))
        elif jump < -SLACK:
            log.info("the clock jumped by %s; minutes already checked are not checked again", jump_text(jump))

    def _start_run(self, route):
        try:
            self._on_due(route)
        except Exception:
            log.exception("could not start the scheduled run of route %r", route.name)

    def _run(self):
        while not self._closing.wait(self._pause()):
            try:
                self.check()
            except Exception:
                log.exception("the schedule check failed; trying again next minute")

    def _pause(self):
        """Seconds until just after the next wall-clock minute: from WAKE_AFTER to a minute and WAKE_AFTER."""
        return MINUTE - self._wall() % MINUTE + WAKE_AFTER
