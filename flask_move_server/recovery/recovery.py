"""The stuck state the server shows, and its signs: a robot that says it is stuck. No rospy.

:class:`Recovery` is told the signs (``detector.py``) by its watch (``watch.py``: ``blocked`` when the
laser sees no motion the odometry claims; ``moving`` when it sees motion again) and by the navigator
(``_judge``: goals move_base aborts soon after they were sent, without the robot moving, while its
footprint lies on a wall of the map where it is localized, or twice while the laser shows it touching
something). Then it stops commanding (the goal under way is *held*: ``Navigator.hold``, move_base lets
go of it, whoever waits for it goes on waiting, ``/status`` says ``stuck``; teleop ends) and says so:
``/status`` ``stuck``, a ``stuck`` event (and the webhook, ``core/happenings.py``), in the owner's
words (``words.py``). Its other half (``way_out.py``) gets the robot out: a goal held is backed out
of and sent again; pushed there by the joystick, it waits for its owner (``back_out`` when asked),
and a push on the same way is refused (``check_push``).

Any command (a goal, ``/stop``, the e-stop, the joystick taking over a held goal) ends a back-out
under way; the laser seeing the robot move again ends a ``stuck`` said without a goal.
"""

import logging
import math
import threading
import time

from flask_move_server.core.errors import Pressed
from flask_move_server.recovery import footprint as footprints
from flask_move_server.recovery import words
from flask_move_server.recovery.detector import QUICK_ABORTS, QuickAborts
from flask_move_server.recovery.way_out import BACKING_OUT, FREE, FRESH, SETTLE, STUCK, WayOut

log = logging.getLogger(__name__)

TOUCH = 0.03  # m: a laser end point this near the footprint touches it
UNHEARD = 1.0  # s: a goal that ended this soon, before any odometry was heard, did not move the robot
LOOK = 3.0  # s a goal aborted at once is held for a fresh scan, to tell a stuck robot from an unreachable goal
SENT_KEPT = 8  # goals whose send time is kept, for the quick-abort count


class Recovery(WayOut):
    """The robot's stuck state and its way out (``/status`` ``stuck``; ``stuck`` events)."""

    def __init__(self, robot, config, footprint, places=None, grid=None, relocalize=None, events=None,
                 set_pose=None, clock=time.monotonic):
        """``robot``: the facade; ``config``: config.StuckConfig; ``footprint``: move_base's padded polygon;
        ``places()``: the active map's waypoints as (name, x, y); ``grid()``: the map in use (a Grid) or None;
        ``relocalize()``: asks localization to look again; ``events``: the bus, for ``stuck`` events;
        ``set_pose(pose, sigma)``: tells localization where the robot is (``/initialpose``)."""
        self._robot = robot
        self._nav = robot.navigator
        self.config = config
        self.footprint = footprint
        self._places = places or (lambda: [])
        self._grid = grid or (lambda: None)
        self._relocalize = relocalize or (lambda: None)
        self._set_pose = set_pose
        self._events = events
        self._clock = clock
        self._lock = threading.Lock()
        self._telling = threading.Lock()  # held while a change is told: events in the order of the changes
        self._closed = threading.Event()
        self._state, self._message, self._since, self._where, self._seq = FREE, None, None, None, None
        self.count = self.freed = 0
        self._tries = {}  # seq -> back-outs for that goal
        self._sent = {}  # seq -> monotonic time it was sent
        self._quick = QuickAborts(config.quick_abort)
        self._blocked_again = threading.Event()
        self._worker = None
        self._asked = False  # a back-out the owner asked for is under way (POST /stuck/back_out)
        self._pressed = None  # +1 / -1: the way the joystick pushed the robot against something
        self.sensing = None  # the watch (watch.py): scans and odometry, set by it
        self._nav.judge_aborts(self._judge)
        self._nav.when_ended(self._goal_ended)

    # what the server shows ---------------------------------------------------------------

    def status(self):
        """``/status`` ``stuck``: ``{"state", "message", "since", "place", "waiting", "count", "freed"}``."""
        with self._lock:
            return self._status()

    def _status(self):
        """Lock held. ``waiting``: stuck with no goal held for it, so it waits for its owner (``back_out``)."""
        return {"state": self._state, "message": self._message, "since": self._since, "place": self._where,
                "waiting": self._state == STUCK and not self._nav.holding(self._seq),
                "count": self.count, "freed": self.freed}

    def _change(self, state, message=None, where=None, seq=None, when=None, freed=False, pressed=None, then=None):
        """A new state, told as a ``stuck`` event (outside the state's lock: a listener may ask for the
        status); only when ``when()`` holds, if given (under the lock). True when changed. ``pressed``: the
        way (+1 ahead, -1 behind) the joystick pushed it against something, kept until the state changes;
        ``then()``, if given, runs once the state changed, before it is told."""
        with self._telling:
            with self._lock:
                if when is not None and not when():
                    return False
                self._pressed = pressed
                if state != FREE and self._state == FREE:
                    self.count += 1
                    self._since = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
                self.freed += 1 if freed else 0
                self._state, self._message, self._seq = state, message, seq
                self._where = where if state != FREE else None
                self._since = self._since if state != FREE else None
                told = self._status()
            if then is not None:
                then()
            if self._events is not None:
                self._events.publish("stuck", told)
        return True

    def _said_without_goal(self):
        """Lock held: a ``stuck`` is said and no goal is held for it (pressed by the joystick, or given up), or
        the owner's asked back-out is under way: what a new command ends."""
        return ((self._state == STUCK and not self._nav.holding(self._seq))
                or (self._asked and self._state == BACKING_OUT))

    # the signs -------------------------------------------------------------------------------

    def goal_sent(self, seq):
        """A new goal (``Robot._send``): a ``stuck`` said without a goal is over; its send time is kept."""
        with self._lock:
            self._sent[seq] = (self._clock(), self._robot.pose.now())
            while len(self._sent) > SENT_KEPT:
                del self._sent[min(self._sent)]
            said = self._state != FREE
        if said:
            self._change(FREE, when=self._said_without_goal)

    def commanded(self):
        """``/stop`` (or the e-stop): a ``stuck`` said is over; a back-out under way ends (its goal was canceled)."""
        self._change(FREE, when=self._said_without_goal)

    def blocked(self):
        """The watch: the odometry says the robot moves, the laser says it does not."""
        if not self.config.enabled:
            return
        if self._state == BACKING_OUT:
            self._blocked_again.set()
            return
        seq = self._nav.under_way()
        where = self._where_now()
        if seq is not None and self._nav.hold(seq, words.blocked(where)):
            self._stuck(seq, words.blocked(where), where)
            return
        teleop = self._robot.teleop_control.status()
        if not teleop["active"] or teleop["by"] == "dock":
            return  # nobody drives it now (a goal that just ended), or it touches its charger: nothing to say
        stop = self._robot.teleop_control.stop
        stop()  # the motors strain against a wall: stop commanding
        way = self.sensing.came() if self.sensing is not None else None
        # stopped again once said: a push that passed check_push before, and came meanwhile, ends too
        if self._change(STUCK, words.pressed(where), where, when=lambda: self._state == FREE, pressed=way, then=stop):
            log.warning("stuck %s: pressed against something while driven by joystick", where)
            self._later(self._put_back, SETTLE)

    def moving(self):
        """The watch: the laser saw the robot move as its odometry says: a ``stuck`` without a goal is over."""
        if self._state == STUCK and self._change(FREE, when=lambda: self._state == STUCK and not self._asked
                                                 and not self._nav.holding(self._seq)):
            self._later(self._put_back, 0.0)  # what the joystick pushed on after it was said

    def _judge(self, seq, said):
        """The navigator, as move_base aborts goal ``seq`` soon after it was sent, the robot not moving: True
        when it holds the goal because the robot may be stuck. Stuck at once when the footprint lies on the
        map where the robot is localized (move_base can neither plan nor turn from there); at the second
        quick abort in a row, when the laser shows it touching something: a worker looks (a fresh scan,
        :meth:`_look_closer`), as this runs in actionlib's thread under its lock."""
        if not self.config.enabled:
            return False
        with self._lock:
            sent = self._sent.get(seq)
        if sent is None:  # aborted before Robot._send told us it was sent: within a millisecond or two
            seconds, moved = 0.0, 0.0
        else:
            seconds, moved = self._clock() - sent[0], self._travel_since(*sent)
        if moved is None and seconds < UNHEARD:
            moved = 0.0  # ended before the odometry was heard: too soon to have gone anywhere
        self._quick.ended("aborted", seconds, moved)
        if self._quick.in_a_row == 0:
            return False
        if self._on_the_map():
            where = self._where_now()
            if not self._nav.hold(seq, words.cornered(where, True), cancel=False):
                return False
            self._said_stuck(seq, seconds, said, "its footprint lies on the map where it is localized")
            self._stuck(seq, words.cornered(where, True), where)
            return True
        if self._quick.in_a_row < QUICK_ABORTS or not self._nav.hold(seq, words.looking(), cancel=False):
            return False
        threading.Thread(target=self._look_closer, args=(seq, said, seconds), name="stuck-look", daemon=True).start()
        return True

    def _look_closer(self, seq, said, seconds):
        """Goal ``seq`` aborted at once, again: stuck if the laser shows the footprint touching something, and
        the robot gets out; else the goal ends as move_base said."""
        deadline = self._clock() + LOOK
        while self.sensing.points(FRESH) is None and self._clock() < deadline and not self._closed.wait(0.05):
            pass  # the watch subscribes to the laser while the goal is held
        points = self.sensing.points(FRESH)
        if not (points and footprints.touching(points, self.footprint, TOUCH)):
            self._nav.end_held(seq, "aborted", said)
            return
        where = self._where_now()
        self._said_stuck(seq, seconds, said, "the laser shows it touching something")
        if self._nav.hold(seq, words.cornered(where, False), cancel=False):
            self._stuck(seq, words.cornered(where, False), where)

    def _travel_since(self, monotonic, ros_time):
        """Metres the robot came since it was at (``monotonic``, ``ros_time``): the localized pose then and now
        (tf keeps 10 s), else the odometry the watch heard; None when neither knows."""
        then, now = self._robot.pose.at(ros_time), self._robot.pose.current()
        if then is not None and now is not None:
            return math.hypot(now.pose.x - then.x, now.pose.y - then.y)
        return self.sensing.travel_since(monotonic) if self.sensing is not None else None

    def _said_stuck(self, seq, seconds, said, why):
        log.warning("goal %d: aborted %.1f s after it was sent (%s), without moving, and %s: stuck", seq,
                    seconds, said or "no reason given", why)

    def _goal_ended(self, seq, state, target, pose, why):
        if state not in ("aborted", "canceled"):
            self._quick.reset()  # arrived (or rejected, stuck): the quick aborts before say nothing more

    def _on_the_map(self):
        """True when the footprint at the localized pose lies on the map's walls (None of either: False)."""
        grid = self._grid()
        reading = self._robot.pose.current()
        return grid is not None and reading is not None and footprints.on_the_map(grid, reading.pose, self.footprint)

    def _where_now(self):
        reading = self._robot.pose.current()
        try:
            places = [(w.name, w.x, w.y) for w in self._places()]
        except Exception:  # the words are a nicety: never lose the stuck state for them
            places = []
        return words.place(reading.pose if reading is not None else None, places)

    # the way out ---------------------------------------------------------------------------

    def check_push(self, linear):
        """``Robot.teleop``: Pressed when ``linear`` m/s would push the robot on against what it is pressed on
        (the laser saw it not move): it only slides its position into the wall and strains the motors."""
        with self._lock:
            way = self._pressed if self._state == STUCK else None
        if way is not None and linear * way > 0:
            raise Pressed(words.pushed(self._where, way))

    def close(self):
        """Stop a back-out under way (the server is stopping). Idempotent."""
        self._closed.set()
        worker = self._worker
        if worker is not None and worker is not threading.current_thread():
            worker.join(2.0)

