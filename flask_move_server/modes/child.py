"""One roslaunch child process tree: started marked, its output logged, stopped whole.

Output goes to the server's own log, line by line, from a reader thread (logger
``flask_move_server.stack``), not to a file per stack: on the robot that is the journal of
flask-move-server.service, where a user already looks, rotated by journald; roslaunch keeps
its per-node log files under ROS_HOME as usual. The last lines are kept for error messages.
"""

import collections
import logging
import os
import re
import signal
import subprocess
import threading
import time

from flask_move_server.process import children

log = logging.getLogger("flask_move_server.stack")

ANSI = re.compile(r"\x1b\[[0-9;]*m|\x1b\][^\x07]*\x07")
DIED = re.compile(r"^\[(?P<proc>[^\]]+)-\d+\] process has died \[pid \d+, exit code (?P<code>-?\d+)")
REQUIRED_DIED = re.compile(r"REQUIRED process \[(?P<proc>[^\]]+)-\d+\] has died")
CANNOT_LAUNCH = re.compile(r"^ERROR: cannot launch node of type \[(?P<pkg>[^/\]]+)/(?P<type>[^\]]+)\]: (?P<why>.*)")
ROSLAUNCH_SAYS = re.compile(r"^(process\[|\[[^\]]+-\d+\] |log file: |ROS_MASTER_URI=|setting /run_id)")
NODE_LOG = re.compile(r" __log:=(\S+?)\]?\.?$")  # the died line's command: the node's own log file
LEVELS = ((re.compile(r"\[ *(ERROR|FATAL)\]|^ERROR|REQUIRED process|process has died"), logging.ERROR),
          (re.compile(r"\[ *WARN\]"), logging.WARNING))
_serials = iter(range(1, 1 << 30))


class StackProcess:
    """``roslaunch ...`` in a session of its own, marked so that every node it starts is found again."""

    def __init__(self, argv, env=None, keep_lines=40):
        self.argv = list(argv)
        self.marker = children.marker_value(os.getpid(), next(_serials))
        # Every node's output line by line: a pipe makes stdout fully buffered, so roscpp's INFO lines came
        # minutes late in 4 KB chunks, spliced into the WARN lines (stderr) between them. rospy's nodes
        # heed PYTHONUNBUFFERED, roscpp's rosconsole (1.13.1 on) flushes each line with the other.
        self.env = dict(env if env is not None else os.environ, PYTHONUNBUFFERED="1",
                        ROSCONSOLE_STDOUT_LINE_BUFFERED="1")
        self.env[children.MARKER] = self.marker
        self.lines = collections.deque(maxlen=keep_lines)
        # In order: ["died", node, exit code, log file, its last line], ["cannot_launch", pkg, type, why].
        # Bounded: a respawning lidar driver with its cable out dies every few seconds, for days.
        self.events = collections.deque(maxlen=50)
        self.changed = threading.Condition()
        self.process = None
        self._reader = None

    def start(self):
        """Start roslaunch; output is read from now on. Raises OSError when roslaunch cannot run."""
        self.process = subprocess.Popen(
            self.argv, env=self.env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=children.die_with_parent)
        self._reader = threading.Thread(target=self._read, name="stack-output", daemon=True)
        self._reader.start()
        log.info("started %s (pid %d)", " ".join(self.argv), self.process.pid)

    def _read(self):
        for raw in self.process.stdout:
            line = ANSI.sub("", raw.decode("utf-8", "replace")).rstrip()
            if line:
                log.log(level_of(line), "%s", line)
                self._note(line)
        self.process.stdout.close()

    def _note(self, line):
        with self.changed:
            self.lines.append(line)
            self._parse(line)
            self.changed.notify_all()

    def _parse(self, line):
        m = DIED.match(line) or REQUIRED_DIED.search(line)
        if m:
            code = int(m.groupdict().get("code") or 0) or None
            log_file = NODE_LOG.search(line)
            self.events.append(["died", m.group("proc"), code, log_file and log_file.group(1), self._said_before()])
            return
        m = CANNOT_LAUNCH.match(line)
        if m:
            self.events.append(["cannot_launch", m.group("pkg"), m.group("type"), m.group("why")])

    def _said_before(self):
        """The last line a node printed before roslaunch reported its death (its reason, often)."""
        for line in reversed(list(self.lines)[:-1]):
            if not ROSLAUNCH_SAYS.match(line):
                return line
        return None

    def exit_code(self):
        """roslaunch's exit status, None while it runs."""
        return self.process.poll() if self.process else None

    def pids(self):
        """Every live process of this tree: roslaunch and every node it started."""
        self.exit_code()  # reaps roslaunch once it ended, so it is not counted as a zombie
        return set(children.marked(self.marker))

    def last_lines(self, count=8):
        with self.changed:
            return list(self.lines)[-count:]

    def stop(self, timeout):
        """Stop the whole tree (see :func:`stop_tree`) and reap roslaunch; returns once all are gone."""
        stop_tree(self.pids, timeout, first=self._roslaunch_group)
        self._reap()

    def _roslaunch_group(self):
        """roslaunch's process group (itself: each node has its own session) while roslaunch runs."""
        return {self.process.pid} if self.process is not None and self.exit_code() is None else set()

    def _reap(self):
        if self.process is not None:
            try:
                self.process.wait(5)
            except subprocess.TimeoutExpired:
                log.error("roslaunch (pid %d) did not end after SIGKILL", self.process.pid)
        if self._reader is not None:
            self._reader.join(2)


def stop_tree(current_pids, timeout, first=None):
    """SIGINT, then SIGTERM to every process ``current_pids()`` names after ``timeout``, then SIGKILL.

    SIGINT goes to ``first()`` when that names any (roslaunch, which SIGINTs each node and
    waits for it), else to all. Never a second SIGINT to a Python node: one arriving during its
    rospy shutdown can leave it hung. The later signals go to every process left, so a wedged
    roslaunch cannot keep its nodes alive. Returns True when all are gone.
    """
    for sig, wait in ((signal.SIGINT, timeout), (signal.SIGTERM, 2.0), (signal.SIGKILL, 5.0)):
        pids = current_pids()
        if not pids:
            return True
        if sig == signal.SIGINT:
            pids = (first and first()) or pids
        else:
            log.warning("the navigation stack still runs: sending %s to %s", sig.name,
                        ", ".join(children.describe(pid) for pid in sorted(pids)))
        children.send(pids, sig)
        if _gone_within(current_pids, wait):
            return True
    return False


def _gone_within(current_pids, timeout):
    deadline = time.monotonic() + timeout
    while current_pids():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.05)
    return True


def level_of(line):
    """The log level of a line of the stack's output.

    Errors and warnings (ROS console's ``[ERROR]``, ``[ WARN]``, roslaunch's own) as such,
    roslaunch's bookkeeping as INFO, and the nodes' chatter (gmapping prints several lines per
    scan) as DEBUG, to spare the journal on an SD card; the nodes' ROS logs keep it in ROS_HOME.
    """
    for pattern, level in LEVELS:
        if pattern.search(line):
            return level
    return logging.INFO if ROSLAUNCH_SAYS.match(line) else logging.DEBUG
