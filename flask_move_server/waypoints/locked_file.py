"""The plumbing under the waypoints file: stamps, reads, the cross-process lock, atomic saves.

Moved out of ``waypoints.py`` (issue 10) so that the model and format stay one
concern and this one can grow the lock timeout and start-up clean-up. A save
writes a temporary file in the same directory, fsyncs it, renames it over the
file and fsyncs the directory, so a crash (even SIGKILL) leaves the old or the
new file whole; the previous good version goes to ``<file>.bak`` first, the same
way. Temporaries are new files of unique names, never opened through a link
planted in the folder; the lock file must not be a link. An
``fcntl`` lock on ``<file>.lock`` serialises writers across processes, and is
given up after a timeout instead of waiting forever on a stuck holder. Pure: no
rospy, no Flask.
"""

import contextlib
import errno
import fcntl
import glob
import logging
import os
import shlex
import stat
import tempfile
import time

from flask_move_server.core.errors import WaypointFileError, WaypointsLocked

log = logging.getLogger(__name__)

LOCK_POLL = 0.02  # seconds between tries for a held lock


def stamp(path):
    """What identifies one version of ``path`` on disk; None when it does not exist."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return None
    return (st.st_ino, st.st_size, st.st_mtime_ns, st.st_ctime_ns)


MAX_TEXT = 4 * 1024 * 1024  # characters: far beyond any waypoints or mode file, far below a Pi's memory


def read(path):
    """The text of ``path``, or None when it does not exist.

    The files read here (waypoints, a map's waypoints, mode.json) are edited by hand, so
    they may be anything: a FIFO or a device such as ``/dev/zero`` (opened without
    blocking and refused, never a hung request or an endless read), or far too big.
    """
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        return None
    except OSError as exc:
        raise WaypointFileError("cannot read {}: {}".format(path, exc))
    try:
        with os.fdopen(fd, encoding="utf-8") as f:
            if not stat.S_ISREG(os.fstat(fd).st_mode):
                raise WaypointFileError("cannot read {}: not a regular file".format(path))
            text = f.read(MAX_TEXT + 1)
    except (OSError, UnicodeDecodeError) as exc:
        if isinstance(exc, WaypointFileError):
            raise
        raise WaypointFileError("cannot read {}: {}".format(path, exc))
    if len(text) > MAX_TEXT:
        raise WaypointFileError("cannot read {}: more than {} characters, too big for a file of "
                                "this kind".format(path, MAX_TEXT))
    return text


@contextlib.contextmanager
def file_lock(lock_path, timeout):
    """An exclusive ``flock`` on a lock file beside the data (the data file is replaced).

    Waits at most ``timeout`` seconds, then raises :class:`WaypointsLocked`: a
    suspended or stuck ``record-waypoints`` must not hang every save forever.
    """
    try:
        fd = os.open(lock_path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)
    except OSError as exc:
        if exc.errno == errno.ELOOP:  # never create or open a file elsewhere through a planted link
            raise WaypointFileError("cannot lock {}: it is a symbolic link, and the lock file must be a file "
                                    "of its own; remove the link (rm {}) and try again".format(
                                        lock_path, shlex.quote(lock_path)))
        raise WaypointFileError("cannot lock {}: {}".format(lock_path, exc.strerror))
    try:
        _acquire(fd, lock_path, timeout)
        yield
    finally:
        os.close(fd)  # closing releases the lock


def _acquire(fd, lock_path, timeout):
    deadline = time.monotonic() + timeout
    while True:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return
        except BlockingIOError:
            if time.monotonic() >= deadline:
                raise WaypointsLocked(lock_path, timeout, lock_holder(lock_path))
            time.sleep(LOCK_POLL)


def lock_holder(lock_path):
    """Who holds the ``flock`` on ``lock_path``, as 'process 1234 (record-waypoints)'; None if unknown.

    Read from Linux's /proc/locks, so the error can name what to resume or stop.
    """
    try:
        st = os.stat(lock_path)
        with open("/proc/locks", encoding="ascii", errors="replace") as f:
            lines = f.read().splitlines()
    except OSError:
        return None
    inode = "{:02x}:{:02x}:{}".format(os.major(st.st_dev), os.minor(st.st_dev), st.st_ino)
    for fields in (line.split() for line in lines):
        if len(fields) > 5 and fields[1] == "FLOCK" and fields[5] == inode:  # waiters have '->' in [1]
            return _describe_process(fields[4])
    return None


def _describe_process(pid):
    if pid == str(os.getpid()):
        return "this process"
    try:
        with open("/proc/{}/cmdline".format(pid), "rb") as f:
            argv = f.read().decode("utf-8", "replace").split("\0")
    except OSError:
        return "process {}".format(pid)
    words = [os.path.basename(a) for a in argv[:2] if a]
    if words and words[0].startswith("python") and len(words) > 1 and not words[1].startswith("-"):
        words = words[1:]  # a console script: 'record-waypoints', not 'python3 record-waypoints'
    return "process {} ({})".format(pid, " ".join(words)[:60])


def new_file_mode():
    """The mode ``open()`` gives a new file under this process's umask.

    mkstemp makes its files 0600 whatever the umask; a file it makes that stays
    (a map, a map's waypoints) gets this instead, so the service's ``UMask=0027``
    lets its group (the user copying a map off the robot) read it, as map_saver's would.
    """
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return 0o666 & ~int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    return 0o644


def atomic_write(path, text, backup_text=None):
    """Write ``text`` to ``path`` so that a crash leaves the old or the new file, whole.

    ``backup_text``, when given, becomes ``path.bak`` first: the caller passes
    the last good version it loaded, never what happens to be on disk now (a
    hand edit in progress must not become the backup). Nothing is written through
    a symbolic link: each file is written to a new temporary one and renamed over
    the name, so a link at ``path`` or ``path.bak`` is replaced, its target untouched. A
    ``text`` longer than :func:`read` takes is refused (WaypointFileError), nothing written.
    """
    if len(text) > MAX_TEXT:  # never a file that read() would refuse: the robot would lose it at the next start
        raise WaypointFileError("cannot save {}: {} characters, more than the {} this file may hold; nothing was "
                                "written".format(path, len(text), MAX_TEXT))
    mode = os.stat(path).st_mode & 0o7777 if os.path.exists(path) else new_file_mode()
    tmp = _write_temporary(path, text, mode)  # first: a full disk fails the save before .bak changes
    try:
        if backup_text is not None:
            _replace(path + ".bak", _write_temporary(path + ".bak", backup_text, mode))
        _replace(path, tmp)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    fsync_dir(os.path.dirname(path))


def _replace(path, tmp):
    """Rename the whole file ``tmp`` over ``path`` (a link there is replaced); ``tmp`` removed if that fails."""
    try:
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _write_temporary(path, text, mode):
    """A new file beside ``path`` holding ``text``, synced; its name.

    mkstemp opens a name of its own making with ``O_CREAT | O_EXCL | O_NOFOLLOW``: a
    file or link planted in the folder is never opened, let alone written through.
    """
    fd, tmp = tempfile.mkstemp(prefix=".{}.".format(os.path.basename(path)), suffix=".tmp",
                               dir=os.path.dirname(path))
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            os.fchmod(f.fileno(), mode)
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    return tmp


def leftovers(path):
    """Temporary files a killed save of ``path`` may have left behind."""
    directory, name = os.path.split(path)
    pattern = os.path.join(glob.escape(directory), ".{}.*.tmp".format(glob.escape(name)))
    found = glob.glob(pattern)
    if os.path.lexists(path + ".bak.tmp"):  # the fixed name saves used before issue 21 (a link: removed)
        found.append(path + ".bak.tmp")
    return sorted(found)


def remove_leftovers(path, timeout):
    """Delete what a killed save left, under the lock so no live save loses its temp file."""
    if not leftovers(path):
        return
    try:
        with file_lock(path + ".lock", timeout):
            for tmp in leftovers(path):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(tmp)
                log.warning("removed %s, left by a save that was killed midway", tmp)
    except WaypointFileError as exc:
        log.warning("left temporary files of %s in place: %s", path, exc)


def fsync_dir(directory):
    """Make the renames in ``directory`` durable: a power cut after the answer keeps them."""
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
