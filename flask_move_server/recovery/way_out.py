"""The way out of a stuck robot: a slow back-out, the position put back, the goal again. No rospy.

:class:`WayOut` is :class:`~flask_move_server.recovery.recovery.Recovery`'s half that acts, in workers
of its own: with a goal held, back out the way the robot came as far as the laser shows room
(``back_out.py``), ask localization to look again, send the same goal again, or end it ``stuck``
after ``stuck.tries`` (``_get_out``); for the owner who asks (``back_out``), the same back-out
alone; whenever stuck, the position that slid with the odometry put back (``_put_back``). It uses
the recovery's state, lock and parts (``_nav``, ``_robot``, ``sensing``, ``_change``, ...).
"""

import logging
import math
import threading

from flask_move_server.core.errors import MoveServerError, NotStuck
from flask_move_server.recovery import footprint as footprints
from flask_move_server.recovery import relocate, words
from flask_move_server.recovery.back_out import BLOCKED, NO_ROOM, PERIOD, BackOut, ended
from flask_move_server.recovery.back_out import DONE as BACKED_OUT

log = logging.getLogger("flask_move_server.recovery.recovery")  # one logger for the stuck robot's lines

FREE, STUCK, BACKING_OUT = "free", "stuck", "backing_out"
SETTLE = 0.5  # s for the robot to come to rest (and a fresh scan to come) before it backs out
MIN_ROOM = 0.05  # m: less room behind than this is none
FRESH = 1.0  # s: an older scan says nothing of the robot now
NOT_STUCK = "The robot is not stuck: there is nothing to back out of."
BUSY = "The robot is {} already: wait for it, or press Stop."
SURE = (0.05, 0.05)  # m, rad: the spread of a position put back by the laser (RViz's click says 0.5 m)


class WayOut:
    """The recovery's workers (a mixin of :class:`~flask_move_server.recovery.recovery.Recovery`)."""

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
        when someone else took over (``seq``: the goal held for it, or None: the owner asked for it).

        Blocked that way too (wedged at an angle: a table's corner beside its back, which the laser shows
        alongside the way back, not in it), it pulls out the other way, once, if the laser shows room there."""
        way = -(self.sensing.came() or 1)  # back the way it came: it drove forward into it, most likely
        outcome = self._back_out_way(seq, where, way)
        if outcome == BLOCKED and self._ours(seq):
            log.info("%s: blocked backing out; trying the other way", "goal {}".format(seq) if seq else "asked")
            other = self._back_out_way(seq, where, -way)
            outcome = outcome if other == NO_ROOM else other
        return outcome

    def _back_out_way(self, seq, where, way):
        """One back-out ``way`` (-1 backwards, +1 forwards): the outcome, or None (someone else took over)."""
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


def _rounded(pose):
    return "x {:.2f}, y {:.2f}, yaw {:.2f}".format(pose.x, pose.y, pose.yaw)
