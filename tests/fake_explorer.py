"""An explorer without a robot, for the web, robotctl and page tests: the Explorer's interface in memory.

``start`` refuses as the real explorer (explore/explorer.py) does, in its words (a bad map name, a saved
name without ``overwrite``, the e-stop, an exploration under way, or whatever ``refusal`` a test sets);
a cancel ends it with the real one's sentence. The test then moves the
exploration on with ``advance(state=..., frontiers=...)``, or ``play()`` runs a whole one on a timer.
Every change is an ``explore`` event on the bus, as the real one publishes. ``attach(robot)`` makes a
fake robot's ``stop`` and e-stop cancel it, as the real facade does.
"""

import datetime
import threading
import time

from flask_move_server.core.errors import ExploreConflict, MapExists
from flask_move_server.maps.catalogue import check_map_name

ACTIVE = ("starting", "exploring", "returning", "saving")
ENDED = ("done", "failed", "canceled")
STOPPED = "Stopped (POST /stop)."
ESTOP = "The e-stop was engaged (POST /estop)."


class FakeExplorer:
    """Answers as an explorer with nothing under way. ``calls`` lists ``(method, arguments)`` in order.

    ``maps``: names saved already (a start to one without ``overwrite`` is 409 ``map_exists``);
    ``estop``: a drive/estop.EStop whose latch refuses a start.
    """

    def __init__(self, events=None, maps=(), estop=None):
        self.events = events
        self.maps = set(maps)
        self.estop = estop
        self.calls = []
        self.refusal = None  # an error the next start raises, once (a run active: ExploreConflict, say)
        self._lock = threading.Lock()
        self._exploration = None
        self._began = None
        self._player = None

    def start(self, save_as, then="navigation", max_minutes=30.0, return_home=True, overwrite=False):
        options = {"save_as": save_as, "then": then, "max_minutes": max_minutes, "return_home": return_home,
                   "overwrite": overwrite}
        self.calls.append(("start", options))
        with self._lock:
            self._refuse(save_as, overwrite)
            self._began = time.monotonic()
            self._exploration = {
                "state": "starting", "frontiers": 0, "known_m2": 0.0, "goals": 0, "unreachable": 0, "elapsed": 0.0,
                "map": None, "message": "Starting mapping.", "save_as": save_as, "then": then,
                "max_minutes": max_minutes, "return_home": return_home, "target": None,
                "started": datetime.datetime.now().astimezone().isoformat(timespec="seconds")}
            shown = dict(self._exploration)
        self._publish(shown)
        return shown

    def _refuse(self, save_as, overwrite):
        if self.refusal is not None:
            refusal, self.refusal = self.refusal, None
            raise refusal
        check_map_name(save_as)
        if self.estop is not None:
            self.estop.refuse_motion("exploring is")
        if self._exploration is not None and self._exploration["state"] in ACTIVE:
            raise ExploreConflict("The robot is already exploring (to save as {!r}): stop it first (POST /stop), "
                                  "or wait until it is done (GET /explore).".format(self._exploration["save_as"]))
        if save_as in self.maps and not overwrite:
            raise MapExists("A map named {!r} is already saved; ask to overwrite it, or pick another name."
                            .format(save_as))

    def current(self):
        with self._lock:
            if self._exploration is None:
                return None
            return dict(self._exploration, elapsed=self._elapsed())

    def cancel(self, reason):
        """End the exploration under way ``canceled``, saying ``reason``; False when none was."""
        self.calls.append(("cancel", reason))
        with self._lock:
            if self._exploration is None or self._exploration["state"] not in ACTIVE:
                return False
        self.advance(state="canceled", target=None, message="{} The map made so far stays in mapping mode, unsaved: "
                     "save it (POST /maps) or explore again.".format(reason.rstrip(".") + "."))
        return True

    def advance(self, **changes):
        """The exploration moved on: ``changes`` to its fields, told as an ``explore`` event; the new EXP."""
        with self._lock:
            if "elapsed" in changes:  # the clock goes on from there
                self._began = time.monotonic() - changes["elapsed"]
            self._exploration.update(changes, elapsed=changes.get("elapsed", self._elapsed()))
            if changes.get("state") == "done":
                self.maps.add(self._exploration["save_as"])
            shown = dict(self._exploration)
        self._publish(shown)
        return shown

    def play(self, steps, period=0.5):
        """Advance through ``steps`` (dicts of changes), one every ``period`` s from the next start (or the one
        under way), in a thread of its own; an exploration ended meanwhile (canceled) is left as it is."""
        def run():
            while self._exploration is None:
                if self._stopping.wait(0.01):
                    return
            for changes in steps:
                if self._stopping.wait(period):
                    return
                with self._lock:
                    over = self._exploration["state"] not in ACTIVE
                if over:
                    return
                self.advance(**changes)

        self._stopping = threading.Event()
        self._player = threading.Thread(target=run, name="fake-explorer", daemon=True)
        self._player.start()

    def attach(self, robot):
        """``robot.stop`` and its e-stop cancel the exploration, as the real facade's do."""
        stop = robot.stop

        def stop_and_cancel(*args):  # the fake robot's e-stop calls its stop too
            self.cancel(ESTOP if robot.estop.latched else STOPPED)
            return stop(*args)

        robot.stop = stop_and_cancel
        return robot

    def close(self):
        if self._player is not None:
            self._stopping.set()
            self._player.join(5)

    def _elapsed(self):
        if self._exploration["state"] in ENDED:
            return self._exploration["elapsed"]
        return round(time.monotonic() - self._began, 1)

    def _publish(self, exploration):
        if self.events is not None:
            self.events.publish("explore", exploration)


def a_whole_exploration(name="flat"):
    """The steps of an exploration that maps a flat, comes back and saves it (for ``play``)."""
    steps = [{"state": "exploring", "frontiers": left, "known_m2": known, "goals": goals, "unreachable": goals // 3,
              "target": [1.0 + goals, 0.5 * goals], "message": "Driving to the frontier nearest the robot."}
             for left, known, goals in ((5, 12.0, 1), (4, 20.5, 2), (3, 42.0, 3), (1, 55.5, 4), (0, 61.0, 5))]
    steps.append({"state": "returning", "target": [0.0, 0.0], "message": "No frontier left: going back to the start."})
    steps.append({"state": "saving", "target": None, "message": "Saving the map as {!r}.".format(name)})
    steps.append({"state": "done", "map": name, "message": "Saved the map {!r}; navigating on it.".format(name)})
    return steps
