"""The e-stop latch: once engaged, nothing moves the robot until someone releases it. Pure.

``POST /estop`` or a press of the e-stop button (:mod:`.estop_button`) engages
the latch. Engaging tells every listener at once (the Robot: halt the motors
through the drive, cancel the goal, end teleop) and from then on the base
controller refuses ``/cmd_vel`` and the Robot refuses goals and teleop. Only
an explicit release (``POST /estop/release``) lifts it, and releasing moves
nothing. Imports neither rospy nor RPi.GPIO, so the latch works with ROS down.
"""

import datetime
import logging
import threading

from flask_move_server.core.errors import EStopHeld, EStopLatched

log = logging.getLogger(__name__)

RELEASE_HOW = "POST /estop/release (or 'robotctl estop release')"


class EStop:
    """The latch: ``engage(source)``, ``release()``, ``status()``; thread-safe."""

    def __init__(self, clock=None):
        self._clock = clock or (lambda: datetime.datetime.now(datetime.timezone.utc))
        self._lock = threading.Lock()
        self._latched = False
        self._source = None
        self._since = None
        self._engagements = 0
        self._listeners = []
        self._release_checks = []

    def when_engaged(self, callback):
        """Call ``callback(source)`` every time the latch is engaged (also when already latched)."""
        self._listeners.append(callback)

    def check_release_with(self, check):
        """``check()`` returns why the latch must stay (a sentence), or None; asked on each release."""
        self._release_checks.append(check)

    @property
    def latched(self):
        return self._latched

    @property
    def engagements(self):
        """How many times the latch was engaged (a press while latched is not one): a listener of
        :meth:`when_engaged` tells a new engagement from a repeated press by it."""
        return self._engagements

    def engage(self, source):
        """Latch (``source``: who, e.g. ``api``, ``button``) and stop everything; True when newly latched."""
        with self._lock:
            newly = not self._latched
            if newly:
                self._latched, self._source, self._since = True, source, self._clock()
                self._engagements += 1
        if newly:
            log.warning("e-stop engaged by %s: motors halted, goals and teleop refused until released", source)
        for callback in self._listeners:  # again on a repeated press: stopping twice is harmless
            _call(callback, source)
        return newly

    def release(self):
        """Lift the latch; EStopHeld while a check (the button still pressed) refuses. Moves nothing."""
        for check in self._release_checks:
            reason = check()
            if reason:
                raise EStopHeld(reason)
        with self._lock:
            was = self._latched
            self._latched, self._source, self._since = False, None, None
        if was:
            log.warning("e-stop released: goals and teleop accepted again")
        return was

    def refuse_motion(self, what):
        """Raise EStopLatched, saying how to release, when latched; ``what``: the refused request."""
        with self._lock:
            if not self._latched:
                return
            source, since = self._source, self._since
        raise EStopLatched(
            "The e-stop is latched (by {} at {}): {} refused. Release it with {} once it is safe "
            "to move.".format(_source_words(source), _iso(since), what, RELEASE_HOW)
        )

    def status(self):
        """The ``estop`` part of ``/status``: latched, source, since (ISO time or null)."""
        with self._lock:
            return {"latched": self._latched, "source": self._source, "since": _iso(self._since)}


def _source_words(source):
    return {"api": "POST /estop", "button": "the e-stop button"}.get(source, source)


def _iso(moment):
    return None if moment is None else moment.isoformat(timespec="milliseconds")


def _call(callback, source):
    """A failing listener is logged; the others still run (a stop must not be skipped)."""
    try:
        callback(source)
    except Exception:
        log.exception("e-stop listener %r failed", callback)
