"""One recording session: what the user types, what RViz clicks, what is saved.

Pure of terminal handling and of rospy: the session gets a saver (server or
file), the ROS side (pose and queued clicks, or anything with the same
methods), a marker publisher and a ``say`` function. Every change is saved at
once and remembered as its inverse, so ``undo`` reverts exactly that change
without clobbering edits others made meanwhile.
"""

import math
import re
import shlex

from flask_move_server.core.errors import BadRequest, MoveServerError, UnknownWaypoint
from flask_move_server.robotctl.text import columns, padded
from flask_move_server.waypoints import check_name, make_waypoint, suggest

HELP = """\
Mark places for the robot:
  NAME                 save the robot's current pose as NAME (also: here NAME)
  click in RViz        "Publish Point" (or "2D Nav Goal" on {goal_topic}, with heading), then type its name
  list                 the waypoints       rename OLD NEW    give a waypoint another name
  delete NAME          remove one          undo              revert the last change
  help                 this text           quit (or Ctrl-C)  leave; everything is saved already
Names with spaces: quote them in commands (rename "living room" "Mum's room")."""

COMMANDS = ("list", "ls", "rename", "mv", "delete", "rm", "undo", "help", "?", "quit", "exit", "here", "save")
_AUTO_NAME = re.compile(r"wp(\d+)$")


class Session:
    """The recorder's state: the click awaiting a name and the undo history."""

    def __init__(self, saver, ros, markers, say=print, auto_names=False, goal_topic="/waypoint_goal"):
        self.saver = saver
        self.ros = ros
        self.markers = markers
        self.say = say
        self.auto_names = auto_names
        self.goal_topic = goal_topic
        self.awaiting = None  # the Click whose name the next line gives
        self.history = []  # (what was done, the operation that undoes it)
        self.running = True

    # input ---------------------------------------------------------------------------

    def handle_line(self, line):
        """Act on one line the user typed; False once the user quits."""
        line = line.strip()
        if self.awaiting is not None:
            click, self.awaiting = self.awaiting, None
            if line:
                self._guard(self.save, line, click.pose, "clicked")
            else:
                self.say("Skipped that click.")
            return self.running
        if line:
            self._guard(self._command, line)
        return self.running

    def handle_clicks(self, limit=None):
        """Take up to ``limit`` queued RViz clicks: name them, or ask for a name; True if more wait."""
        while not self.ros.problems.empty():
            self.say(self.ros.problems.get_nowait())
        count = self.ros.clicks.qsize() if limit is None else limit
        for _ in range(count):
            if self.awaiting is not None or self.ros.clicks.empty():
                break
            click = self.ros.clicks.get_nowait()
            if self.auto_names:
                self._guard(self.save, self.next_auto_name(), click.pose, "clicked")
            else:
                self.awaiting = click
                self.say("{} at {}. Name it (empty line skips):".format(click.tool, _where(click.pose)))
        return self.awaiting is None and not self.ros.clicks.empty()

    def refresh(self):
        """Show the saved waypoints in RViz (others may have changed them)."""
        self.markers.show(self.saver.all())

    # commands --------------------------------------------------------------------------

    def _command(self, line):
        words = _split(line)
        verb, args = words[0].lower(), words[1:]
        if verb not in COMMANDS or (verb in ("list", "ls", "undo", "help", "?", "quit", "exit") and args):
            return self.save_here(" ".join(words))
        if verb in ("here", "save"):
            return self.save_here(" ".join(args) if len(args) > 1 else _one(args, "here NAME"))
        if verb in ("list", "ls"):
            return self.show_list()
        if verb in ("rename", "mv"):
            if len(args) != 2:
                return self.say('Use: rename OLD NEW (quote names with spaces: rename "living room" lounge).')
            return self.rename(*args)
        if verb in ("delete", "rm"):
            return self.delete(" ".join(args) if len(args) > 1 else _one(args, "delete NAME"))
        if verb == "undo":
            return self.undo()
        if verb in ("quit", "exit"):
            self.running = False
            return None
        return self.say(HELP.format(goal_topic=self.goal_topic))

    def save_here(self, name):
        """Save the robot's current pose as ``name``."""
        if name:
            self.save(name, self.ros.current_pose(), "here")

    def save(self, name, pose, how):
        """Save ``pose`` as waypoint ``name`` (new or replacing), remembering how to undo it."""
        waypoint = make_waypoint(name, pose.x, pose.y, pose.yaw)
        before = {wp.name: wp for wp in self.saver.all()}.get(waypoint.name)
        self.saver.put(waypoint)
        undo = ("put", before) if before else ("delete", waypoint.name)
        self._changed("{} {}".format("replaced" if before else "saved", name), undo)
        self.say("{} {} at {} ({}), in {}.".format(
            "Replaced" if before else "Saved", name, _where(pose), how, self.saver.where))

    def rename(self, old, new):
        old, new = check_name(old), check_name(new)
        self.saver.rename(old, new)
        self._changed("renamed {} to {}".format(old, new), ("rename", new, old))
        self.say("Renamed {} to {}.".format(old, new))

    def delete(self, name):
        name = check_name(name)
        known = {wp.name: wp for wp in self.saver.all()}
        if name not in known:
            raise UnknownWaypoint(name, suggest(name, known))
        self.saver.delete(name)
        self._changed("deleted {}".format(name), ("put", known[name]))
        self.say("Deleted {}.".format(name))

    def undo(self):
        """Revert the last change made in this session."""
        if not self.history:
            return self.say("Nothing to undo.")
        what, (op, *args) = self.history[-1]
        if op == "put":
            self.saver.put(args[0])
        elif op == "delete":
            self.saver.delete(args[0])
        else:
            self.saver.rename(*args)
        self.history.pop()
        self.refresh()
        return self.say("Undone: {}.".format(what))

    def show_list(self):
        waypoints = self.saver.all()
        if not waypoints:
            return self.say("No waypoints yet in {}.".format(self.saver.where))
        width = max(columns(wp.name) for wp in waypoints)
        for wp in waypoints:
            self.say("  {}  x {:7.2f}  y {:7.2f}  yaw {:6.2f} ({:4.0f} deg)".format(
                padded(wp.name, width), wp.x, wp.y, wp.yaw, math.degrees(wp.yaw)))
        return None

    def next_auto_name(self):
        """``wpN`` one past the highest ``wpN`` saved so far."""
        numbers = [int(m.group(1)) for m in (_AUTO_NAME.match(wp.name) for wp in self.saver.all()) if m]
        return "wp{}".format(max(numbers, default=0) + 1)

    # internals ---------------------------------------------------------------------------

    def _changed(self, what, undo):
        self.history.append((what, undo))
        self.refresh()

    def _guard(self, action, *args):
        """Run ``action``; a user's mistake or a refused save is one line, never fatal."""
        try:
            action(*args)
        except MoveServerError as exc:
            self.say("Not saved: {}".format(exc) if action == self.save else str(exc))


def _split(line):
    """The words of ``line``, quoted ones whole; an apostrophe in a name (Mum's room) is no quote."""
    try:
        return shlex.split(line) or [line]
    except ValueError:  # an unbalanced quote, as an apostrophe is: only "..." quotes then
        pass
    words = shlex.shlex(line, posix=True)
    words.quotes, words.escape, words.whitespace_split, words.commenters = '"', "", True, ""
    try:
        return list(words) or [line]
    except ValueError:  # an unbalanced " too: take the line as it is
        return line.split()


def _one(args, usage):
    if len(args) != 1:
        raise BadRequest("Use: {}".format(usage))
    return args[0]


def _where(pose):
    return "x {:.2f}, y {:.2f}, yaw {:.2f}".format(pose.x, pose.y, pose.yaw)
