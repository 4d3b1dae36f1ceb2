"""Child processes that never outlive the server: the parent-death signal and marked process trees.

roslaunch starts every node in a session of its own (``os.setsid``), so neither the process
group nor the parent link finds them all once roslaunch is gone. What does survive is the
environment: every process roslaunch starts inherits it. A child tree started with
``MARKER=<server pid>:<n>`` in its environment is therefore found, whole, by reading
``/proc/*/environ`` (our own processes only: other users' are unreadable and skipped).
Pure stdlib, Linux.
"""

import os
import signal

MARKER = "FLASK_MOVE_SERVER_STACK"


def die_with_parent(sig=signal.SIGTERM):
    """In a child (``preexec_fn``): get ``sig`` when the server dies without closing (Linux).

    SIGTERM, not SIGKILL: roslaunch and rosmaster stop their own children on SIGTERM. Linux sends
    it when the *thread* that started the child ends: start children from a thread that lives as
    long as they should (the main thread, or one kept for the purpose, as ``modes/launched.py`` does).
    """
    try:
        import ctypes

        ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, sig)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def marker_value(owner_pid, serial):
    """The marker a child tree started by ``owner_pid`` carries (``PID:N``)."""
    return "{}:{}".format(owner_pid, serial)


def marked(value=None):
    """Pids of live processes carrying MARKER (equal to ``value``, or any value when None): {pid: value}."""
    found = {}
    for name in os.listdir("/proc"):
        if not name.isdigit() or _is_zombie(name):
            continue
        mark = _marker_of(name)
        if mark is not None and (value is None or mark == value):
            found[int(name)] = mark
    return found


def orphans():
    """Marked processes whose owning server is gone (a server killed with no chance to stop them)."""
    result = []
    for pid, mark in marked().items():
        owner = mark.split(":", 1)[0]
        if owner.isdigit() and not os.path.exists("/proc/" + owner):
            result.append(pid)
    return result


def describe(pid):
    """``pid (program)`` for messages: the program a process runs (the script, for Python ones)."""
    try:
        with open("/proc/{}/cmdline".format(pid), "rb") as f:
            argv = [a.decode(errors="replace") for a in f.read().split(b"\0") if a]
    except OSError:
        return str(pid)
    words = [a for a in argv if not a.startswith("-")]
    program = words[1] if len(words) > 1 and os.path.basename(words[0]).startswith("python") else (words or ["?"])[0]
    return "{} ({})".format(pid, os.path.basename(program))


def send(pids, sig):
    """Send ``sig`` to each pid that still exists."""
    for pid in pids:
        try:
            os.kill(pid, sig)
        except (ProcessLookupError, PermissionError):
            pass


def _marker_of(pid):
    prefix = MARKER.encode() + b"="
    try:
        with open("/proc/{}/environ".format(pid), "rb") as f:
            entries = f.read().split(b"\0")
    except OSError:
        return None
    for entry in entries:
        if entry.startswith(prefix):
            return entry[len(prefix):].decode("ascii", "replace")
    return None


def _is_zombie(pid):
    try:
        with open("/proc/{}/stat".format(pid), "rb") as f:
            stat = f.read()
    except OSError:
        return True
    return stat[stat.rfind(b")") + 2:][:1] in (b"Z", b"X")
