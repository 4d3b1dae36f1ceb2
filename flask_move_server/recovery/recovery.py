"""The stuck state the server shows, and the way out: the goal held, a back-out, the goal again. No rospy.

:class:`Recovery` is told the signs (``detector.py``) by its watch (``watch.py``: ``blocked`` when the
laser sees no motion the odometry claims) and by the navigator (``_judge``: a goal move_base
aborted soon after it was sent, again, with the robot touching something). Then:

1. it stops commanding: the goal under way is *held* (``Navigator.hold``: move_base lets go of it,
   whoever waits for it goes on waiting, ``/status`` says ``stuck``), teleop ends;
2. it says so: ``/status`` ``stuck``, a ``stuck`` event (and the webhook, ``core/happenings.py``),
   in the owner's words (``words.py``);
3. with a goal held (the robot drove itself there), it backs out by itself when the laser shows
   room behind (``back_out.py``), asks localization to look again (AMCL's
   ``request_nomotion_update``), and sends the same goal again: a run, an exploration or a waiting
   ``/goto`` sees its goal go on. At most ``stuck.tries`` back-outs a goal; then, or with no room
   behind, the goal ends ``stuck`` and the robot waits for its owner. Pressed against something by
   the joystick, it only says so (the owner is driving).

Any command (a goal, ``/stop``, the e-stop, the joystick taking over a held goal) ends a back-out
under way; the laser seeing the robot move again ends a ``stuck`` said without a goal.
"""

import logging
import math
import threading
import time

from flask_move_server.core.errors import MoveServerError, NotStuck, Pressed
from flask_move_server.recovery import footprint as footprints
from flask_move_server.recovery import relocate, words
from flask_move_server.recovery.back_out import DONE as BACKED_OUT
from flask_move_server.recovery.back_out import NO_ROOM, PERIOD, BackOut, ended
from flask_move_server.recovery.detector import QUICK_ABORTS, QuickAborts

log = logging.getLogger(__name__)

FREE, STUCK, BACKING_OUT = "free", "stuck", "backing_out"
SETTLE = 0.5  # s for the robot to come to rest (and a fresh scan to come) before it backs out
TOUCH = 0.03  # m: a laser end point this near the footprint touches it
MIN_ROOM = 0.05  # m: less room behind than this is none
FRESH = 1.0  # s: an older scan says nothing of the robot now
NOT_STUCK = "The robot is not stuck: there is nothing to back out of."
BUSY = "The robot is {} already: wait for it, or press Stop."
SURE = (0.05, 0.05)  # m, rad: the spread of a position put back by the laser (RViz's click says 0.5 m)
UNHEARD = 1.0  # s: a goal that ended this soon, before any odometry was heard, did not move the robot
LOOK = 3.0  # s a goal aborted at once is held for a fresh scan, to tell a stuck robot from an unreachable goal
SENT_KEPT = 8  # goals whose send time is kept, for the quick-abort count


class Recovery:
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

    def _change(self, state, message=None, where=None, seq=None, when=None, freed=False, pressed=None):
        """A new state, told as a ``stuck`` event (outside the state's lock: a listener may ask for the
        status); only when ``when()`` holds, if given (under the lock). True when changed. ``pressed``: the
        way (+1 ahead, -1 behind) the joystick pushed it against something, kept until the state changes."""
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
        if not self._robot.teleop_control.status()["active"]:
            return  # nobody drives it now (a goal that just ended): nothing to say
        self._robot.teleop_control.stop()  # the motors strain against a wall: stop commanding
        way = self.sensing.came() if self.sensing is not None else None
        if self._change(STUCK, words.pressed(where), where, when=lambda: self._state == FREE, pressed=way):
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

    def _stuck(self, seq, message, where):
        """Goal ``seq`` is held: say so, then back out in a worker of its own."""
        self._robot.teleop_control.end_command()
        self._change(STUCK, message, where, seq)
        worker = threading.Thread(target=self._get_out, args=(seq, where), name="stuck-back-out", daemon=True)
        self._worker = worker
        log.warning("goal %d: %s", seq, message)
        worker.start()

    def _get_out(self, seq, where):
        try:
            self._try_back_out(seq, where)
        except Exception as exc:  # a worker must end what it holds, whatever went wrong
            log.exception("backing out failed")
            self._give_up(seq, words.no_way_out(where, "Backing out failed: {}.".format(exc)))
        finally:
            self._robot.teleop_control.end_command()

    def _try_back_out(self, seq, where):
        """Goal ``seq`` got the robot stuck: back out, then send it again; or it ends ``stuck``."""
        tries = self._tries.get(seq, 0)
        if not self.config.back_out:
            return self._give_up(seq, words.no_way_out(where, words.back_out_off()))
        if tries >= self.config.tries:
            return self._give_up(seq, words.no_way_out(where, words.tried(tries)))
        if self._closed.wait(SETTLE) or not self._nav.holding(seq):
            return self._owner_took_over(seq)
        self._put_back()
        outcome = self._back_out(seq, where)
        if outcome is None:
            return self._owner_took_over(seq)
        if outcome != BACKED_OUT:
            return self._give_up(seq, words.no_room(where) if outcome == NO_ROOM
                                 else words.no_way_out(where, words.got_nowhere()))
        self._relocalize()
        self._tries[seq] = tries + 1
        self._quick.reset()
        if self._nav.retry(seq):
            self._change(FREE, freed=True)
            log.info("goal %d: %s", seq, words.freed(where, None))
        else:
            self._owner_took_over(seq)

    def _back_out(self, seq, where):
        """Back out the way the robot came, as far as the laser shows room: the outcome (back_out.py), or None
        when someone else took over (``seq``: the goal held for it, or None: the owner asked for it)."""
        way = -(self.sensing.came() or 1)  # back the way it came: it drove forward into it, most likely
        room = self._room(self.config.back_out_distance, way)
        if room is None or room < MIN_ROOM:
            return NO_ROOM if self._ours(seq) else None
        distance = min(self.config.back_out_distance, room)
        message = words.backing_out(where, distance, way, again=seq is not None)
        if not self._change(BACKING_OUT, message, where, seq, when=lambda: self._ours(seq)):
            return None
        if seq is not None:
            self._nav.say(seq, message)
        outcome = self._drive_back(seq, distance, way)
        self._robot.teleop_control.stop()
        return outcome

    def back_out(self):
        """The owner asks a robot that said it is stuck, and waits, to back out (``POST /stuck/back_out``).

        NotStuck when it is free, or backing out already; EStopLatched while the e-stop is on.
        """
        self._robot.refuse_motion("backing out is")
        with self._lock:
            state, seq, where = self._state, self._seq, self._where
            if state != STUCK or self._nav.holding(seq):
                raise NotStuck(NOT_STUCK if state == FREE else BUSY.format(state.replace("_", " ")))
            self._asked = True
        self._later(lambda: self._asked_back_out(where), 0.0, "stuck-back-out")

    def _asked_back_out(self, where):
        try:
            outcome = self._back_out(None, where)
        finally:
            self._asked = False
            self._robot.teleop_control.end_command()
        if outcome == BACKED_OUT:
            self._relocalize()
            self._change(FREE, freed=True, when=lambda: self._state == BACKING_OUT)
        elif outcome is not None:
            message = words.no_room(where) if outcome == NO_ROOM else words.no_way_out(where, words.got_nowhere())
            self._change(STUCK, message, where, when=lambda: self._state in (STUCK, BACKING_OUT))

    def _ours(self, seq):
        """True while a back-out may go on: goal ``seq`` still held, or (None) the owner's asked one not taken over."""
        if seq is not None:
            return self._nav.holding(seq)
        return self._asked and self._state in (STUCK, BACKING_OUT)

    def check_push(self, linear):
        """``Robot.teleop``: Pressed when ``linear`` m/s would push the robot on against what it is pressed on
        (the laser saw it not move): it only slides its position into the wall and strains the motors."""
        with self._lock:
            way = self._pressed if self._state == STUCK else None
        if way is not None and linear * way > 0:
            raise Pressed(words.pushed(self._where, way))

    def owner_drives(self):
        """The joystick (``Robot.teleop``): a back-out the owner asked for ends; they drive now."""
        if self._asked:
            self._change(FREE, when=lambda: self._asked and self._state == BACKING_OUT)
            self._asked = False

    def _drive_back(self, seq, distance, way):
        """Back out up to ``distance`` (``way`` -1 backwards, +1 forwards): the outcome (back_out.py), or None
        when someone else took over."""
        back_out, start = BackOut(distance, self.config.back_out_speed), self._clock()
        self._blocked_again.clear()
        self.sensing.restart_motion()
        origin = self.sensing.odometry()
        while not self._closed.is_set():
            if not self._ours(seq) or self._robot.estop.latched:
                return None
            backed = self.sensing.travel_from(origin) or 0.0
            step = back_out.next(self._clock() - start, backed, self._room(distance - backed, way),
                                 self._blocked_again.is_set())
            if ended(step):
                log.info("%s: backing out ended %s after %.2f m", "goal {}".format(seq) if seq else "asked", step,
                         backed)
                return step
            self._robot.teleop_control.command(-step * way, 0.0, by="back_out")
            self._closed.wait(PERIOD)
        return None

    def _put_back(self):
        """Localization slid with the odometry the laser did not see: tell it where the laser fits the map
        (relocate.py), when that is clearly better than where it believes the robot is."""
        slip = self.sensing.slip() if self.sensing is not None else None
        if self._set_pose is None or slip is None or not relocate.slipped(slip):
            return
        grid, reading, points = self._grid(), self._robot.pose.current(), self.sensing.points(FRESH)
        if grid is None or reading is None or not points:
            return
        found = relocate.put_back(grid, reading.pose, slip, points)
        if found is None:
            return
        pose, before, after = found
        try:
            self._set_pose(pose, SURE)
        except MoveServerError as exc:
            log.warning("could not put the robot's position back: %s", exc)
            return
        self.sensing.forget_slip()
        log.info("the robot's position slid %.2f m with its odometry: put back to %s (the laser on the map's walls "
                 "%.0f %% there, %.0f %% before)", math.hypot(slip.x, slip.y), _rounded(pose), after * 100,
                 before * 100)

    def _later(self, job, delay, name="stuck-put-back"):
        """``job()`` in a thread of its own after ``delay`` s (not in a ROS callback's thread, nor a request's)."""
        def run():
            if not self._closed.wait(delay):
                try:
                    job()
                except Exception:  # the stuck state stands without it
                    log.exception("%s failed", name)
        thread = threading.Thread(target=run, name=name, daemon=True)
        self._worker = thread if name == "stuck-back-out" else self._worker
        thread.start()

    def _room(self, reach, way):
        """Metres clear for the footprint ``way`` (-1 behind, +1 ahead), at most ``reach``; None: no fresh scan."""
        points = self.sensing.points(FRESH) if self.sensing is not None else None
        if points is None:
            return None
        return footprints.room_along(points, self.footprint, max(reach, 0.0) + self.config.clearance,
                                      self.config.clearance, way=way)

    def _give_up(self, seq, message):
        """The robot cannot get itself out: goal ``seq`` ends ``stuck``, the robot waits for its owner."""
        self._nav.end_stuck(seq, message)
        self._change(STUCK, message, self._where, seq)
        log.warning("goal %d: %s", seq, message)

    def _owner_took_over(self, seq):
        """Someone else commanded the robot while it was held (a goal, the joystick, stop): free again."""
        self._change(FREE, when=lambda: self._seq == seq and self._state != FREE)

    def close(self):
        """Stop a back-out under way (the server is stopping). Idempotent."""
        self._closed.set()
        worker = self._worker
        if worker is not None and worker is not threading.current_thread():
            worker.join(2.0)


def _rounded(pose):
    return "x {:.2f}, y {:.2f}, yaw {:.2f}".format(pose.x, pose.y, pose.yaw)
