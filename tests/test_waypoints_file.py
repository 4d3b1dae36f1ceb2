"""No waypoint lost to the file (issue 10): empty or cut-short files, a stuck lock, alias bombs, kills mid-save.

Real files, real flock held by a second real process, a second process editing
the file in place while this one reads, and SIGKILL in the middle of saves.
"""

import logging
import os
import random
import signal
import subprocess
import sys
import textwrap
import threading
import time

import pytest

from flask_move_server.core.errors import WaypointFileError, WaypointsLocked
from flask_move_server.waypoints import make_waypoint
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.waypoints.yaml_format import parse
from tests.test_waypoints import SEED, SEED_WRITTEN, WRITER

SEED_NAMES = ["kitchen", "office", "dock"]
SEED_SET = set(parse(SEED).values())


@pytest.fixture
def seed_file(tmp_path):
    path = tmp_path / "waypoints.yaml"
    path.write_text(SEED)
    return path


def _bak(path):
    return path.with_name(path.name + ".bak")


# item 8: an empty or cut-short file is a problem, not a deletion ----------------------------------------

CUT_SHORT = [
    pytest.param("", id="0-byte"),
    pytest.param("\n  \n", id="blank"),
    pytest.param("waypoints:\n", id="cut-after-the-key"),
    pytest.param("# waypoints\n", id="comment-only"),
    pytest.param(SEED[: SEED.index("-1.57") + 4], id="cut-mid-number"),
    pytest.param("waypoints:\n  kitchen: [1.23, 4.56, 0.79]\n  office:\n    x: 5.67\n    y: 2.34\n    yaw: -1.",
                 id="cut-mid-number-of-a-block-entry"),  # parses (yaw -1.0): judged cut by where it stops
    pytest.param("waypoints:\n  kitchen: [1.23, 4.", id="cut-mid-entry"),
]


@pytest.mark.parametrize("text", CUT_SHORT)
def test_an_empty_or_cut_short_file_keeps_the_last_good_set_and_refuses_changes(seed_file, text):
    store = WaypointStore(seed_file)
    store.put(make_waypoint("dock", 0.0, 0.0, 0.0))  # a save: the .bak is now the seed
    bak_before = _bak(seed_file).read_text()
    seed_file.write_text(text)  # an editor writing in place, a failed printf > file
    assert set(store.all()) == SEED_SET
    assert store.get("office").yaw == -1.57
    assert store.problem
    for _ in range(2):  # the issue: two PUTs used to replace both the file and its .bak
        with pytest.raises(WaypointFileError) as err:
            store.put(make_waypoint("porch", 1, 1, 1))
        message = str(err.value)
        assert str(seed_file) in message and "nothing was changed" in message
        assert "{}.bak".format(seed_file) in message and "waypoints: {}" in message
    with pytest.raises(WaypointFileError):
        store.delete("kitchen")
    assert seed_file.read_text() == text
    assert _bak(seed_file).read_text() == bak_before


def test_a_removed_file_keeps_the_last_good_set(seed_file):
    store = WaypointStore(seed_file)
    seed_file.unlink()  # some editors remove the file for a moment while saving
    assert set(store.all()) == SEED_SET
    with pytest.raises(WaypointFileError, match="is missing"):
        store.put(make_waypoint("porch", 1, 1, 1))
    assert not seed_file.exists()


def test_waypoints_empty_mapping_deletes_everything_on_purpose(seed_file):
    store = WaypointStore(seed_file)
    seed_file.write_text("waypoints: {}\n")
    assert store.all() == [] and store.problem is None
    store.put(make_waypoint("porch", 1, 1, 1))
    assert [w.name for w in WaypointStore(seed_file).all()] == ["porch"]
    assert _bak(seed_file).read_text() == "waypoints: {}\n"


def test_fixing_the_file_lifts_the_problem(seed_file):
    store = WaypointStore(seed_file)
    seed_file.write_text("")
    with pytest.raises(WaypointFileError):
        store.put(make_waypoint("porch", 1, 1, 1))
    seed_file.write_text(SEED + "  garage: [7.0, 8.0, 0.5]\n")
    store.put(make_waypoint("porch", 1, 1, 1))
    assert store.problem is None
    assert [w.name for w in store.all()] == SEED_NAMES + ["garage", "porch"]


def test_an_empty_file_at_start_up_is_refused_while_the_bak_holds_waypoints(seed_file):
    WaypointStore(seed_file).put(make_waypoint("porch", 1, 1, 1))  # .bak: the seed
    seed_file.write_text("")  # a failed printf > file, then a restart
    store = WaypointStore(seed_file)  # starts, serving none, saying why
    assert store.all() == []
    assert "is empty" in store.problem and "had 3 waypoints" in store.problem
    with pytest.raises(WaypointFileError) as err:
        store.put(make_waypoint("garage", 2, 2, 2))
    assert "is empty" in str(err.value) and "had 3 waypoints" in str(err.value)
    assert seed_file.read_text() == "" and _bak(seed_file).read_text() == SEED


def test_a_fresh_or_deliberately_empty_file_still_starts_empty(tmp_path):
    path = tmp_path / "w.yaml"
    path.write_text("")
    assert WaypointStore(path).all() == []
    path.write_text("waypoints:")  # no .bak: nothing to lose
    store = WaypointStore(path)
    assert store.put(make_waypoint("hall", 1, 2, 3)) is True


def test_the_bak_is_the_last_good_set_loaded_not_what_is_on_disk_while_saving(seed_file):
    store = WaypointStore(seed_file)
    store.put(make_waypoint("porch", 1, 1, 1))
    assert _bak(seed_file).read_text() == SEED
    store.put(make_waypoint("garage", 2, 2, 2))
    assert set(parse(_bak(seed_file).read_text())) == set(SEED_NAMES + ["porch"])


IN_PLACE_EDITOR = textwrap.dedent("""\
    import sys, time
    path, text, seconds = sys.argv[1], sys.argv[2], float(sys.argv[3])
    end = time.monotonic() + seconds
    rounds = 0
    while time.monotonic() < end:
        with open(path, "r+") as f:  # an editor saving in place: truncate, then write in pieces
            f.truncate(0)
            for i in range(0, len(text), 9):
                f.write(text[i:i + 9])
                f.flush()
                time.sleep(0.0005)
        rounds += 1
    print(rounds)
    """)


def test_readers_racing_an_in_place_edit_never_see_zero_or_wrong_waypoints(seed_file):
    store = WaypointStore(seed_file)
    seed_file.write_text(SEED_WRITTEN)
    editor = subprocess.Popen([sys.executable, "-c", IN_PLACE_EDITOR, str(seed_file), SEED_WRITTEN, "4"],
                              stdout=subprocess.PIPE, text=True)
    reads = 0
    while editor.poll() is None:
        seen = set(store.all())
        assert seen, "a reader saw zero waypoints while the file was being rewritten"
        assert seen <= SEED_SET, "a reader saw a waypoint the file never held: {}".format(seen - SEED_SET)
        reads += 1
    rounds, _ = editor.communicate()
    assert editor.returncode == 0 and int(rounds) > 10
    assert reads > 10
    seed_file.write_text(SEED_WRITTEN)
    assert set(store.all()) == SEED_SET


# item 9: the file lock has a timeout; reads never wait on it --------------------------------------------

LOCK_HOLDER = textwrap.dedent("""\
    import fcntl, os, sys, time
    fd = os.open(sys.argv[1], os.O_RDWR | os.O_CREAT, 0o644)
    fcntl.flock(fd, fcntl.LOCK_EX)
    print("held", flush=True)
    time.sleep(120)
    """)


@pytest.fixture
def lock_holder(seed_file):
    """A second process holding the waypoints file's lock, like a suspended record-waypoints."""
    proc = subprocess.Popen([sys.executable, "-c", LOCK_HOLDER, str(seed_file) + ".lock"],
                            stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "held"
    yield proc
    proc.kill()
    proc.communicate()


def _in_thread(fn):
    """Run ``fn`` in a daemon thread; the thread, with its outcome in ``.outcome``."""
    def run():
        try:
            thread.outcome = fn()
        except Exception as exc:  # noqa: BLE001 - the test inspects it
            thread.outcome = exc

    thread = threading.Thread(target=run, daemon=True)
    thread.outcome = None
    thread.start()
    return thread


def test_a_held_file_lock_makes_a_change_give_up_with_an_error_naming_it(seed_file, lock_holder):
    store = WaypointStore(seed_file)
    writer = _in_thread(lambda: store.put(make_waypoint("porch", 1, 1, 1)))
    time.sleep(0.3)  # the writer is waiting for the lock now
    reader = _in_thread(lambda: (store.all(), store.get("kitchen")))
    reader.join(10)
    assert not reader.is_alive(), "a read waited behind a writer stuck on the file lock"
    assert set(reader.outcome[0]) == SEED_SET
    writer.join(30)
    assert not writer.is_alive(), "a change waited for the file lock without end"
    assert isinstance(writer.outcome, WaypointsLocked)
    message = str(writer.outcome)
    assert "{}.lock".format(seed_file) in message and "record-waypoints" in message
    assert "process {} (".format(lock_holder.pid) in message  # who to resume or stop
    assert seed_file.read_text() == SEED


def test_the_change_goes_through_once_the_lock_is_released(seed_file, lock_holder):
    store = WaypointStore(seed_file, lock_timeout=0.2)
    with pytest.raises(WaypointsLocked):
        store.delete("kitchen")
    lock_holder.kill()
    lock_holder.wait()
    store.delete("kitchen")
    assert [w.name for w in WaypointStore(seed_file).all()] == ["office", "dock"]


# item 10: small files, big trouble ----------------------------------------------------------------------

ALIAS_BOMB = textwrap.dedent("""\
    waypoints:
      bomb:
        x: [&a [0, 0, 0, 0, 0, 0, 0, 0, 0], &b [*a, *a, *a, *a, *a, *a, *a, *a, *a],
            &c [*b, *b, *b, *b, *b, *b, *b, *b, *b], &d [*c, *c, *c, *c, *c, *c, *c, *c, *c],
            &e [*d, *d, *d, *d, *d, *d, *d, *d, *d], [*e, *e, *e, *e, *e, *e, *e, *e, *e]]
        y: 0
        yaw: 0
    """)


def test_anchors_and_aliases_are_refused_with_a_short_message(tmp_path):
    path = tmp_path / "w.yaml"
    path.write_text(ALIAS_BOMB)
    assert len(ALIAS_BOMB) < 400
    store = WaypointStore(path)
    assert "anchors and aliases" in store.problem
    assert len(store.problem) < 1500


def test_an_alias_bomb_edited_in_keeps_the_problem_and_the_log_small(seed_file, caplog):
    store = WaypointStore(seed_file)
    seed_file.write_text(ALIAS_BOMB)
    with caplog.at_level(logging.INFO):
        assert set(store.all()) == SEED_SET
    assert "anchors and aliases" in store.problem and len(store.problem) < 1000
    assert caplog.records and max(len(r.getMessage()) for r in caplog.records) < 1500


def test_an_error_quoting_a_huge_entry_is_bounded(tmp_path):
    path = tmp_path / "w.yaml"
    path.write_text("waypoints:\n  big: [{}]\n".format(", ".join(["1"] * 50000)))
    problem = WaypointStore(path).problem
    assert "expected [x, y, yaw]" in problem and len(problem) < 1500


def test_leftover_temp_files_of_a_killed_save_are_removed_at_start_up(seed_file, caplog):
    folder = seed_file.parent
    leftovers = [folder / ".waypoints.yaml.k1ll3d.tmp", folder / "waypoints.yaml.bak.tmp"]
    others = [folder / ".other.yaml.abc.tmp", folder / "notes.tmp", _bak(seed_file)]
    for f in leftovers + others:
        f.write_text("waypoints:\n  half")
    with caplog.at_level(logging.WARNING):
        assert set(WaypointStore(seed_file).all()) == SEED_SET
    assert [f for f in leftovers if f.exists()] == []
    assert all(f.exists() for f in others)
    assert all(any(str(f) in r.getMessage() for r in caplog.records) for f in leftovers)


def test_sigkill_during_saves_leaves_a_whole_file_and_the_next_start_cleans_up(tmp_path):
    path = tmp_path / "w.yaml"
    rng = random.Random(10)
    for round_ in range(12):
        prefix = "r{}_".format(round_)
        proc = subprocess.Popen([sys.executable, "-c", WRITER, str(path), prefix, "100000"],
                                stdout=subprocess.PIPE, text=True)
        assert proc.stdout.readline().startswith("ack")
        time.sleep(rng.uniform(0, 0.05))
        os.kill(proc.pid, signal.SIGKILL)
        rest, _ = proc.communicate()
        acked = 1 + sum(1 for line in rest.splitlines() if line.startswith("ack"))
        assert parse(_bak(path).read_text())  # the backup is whole too
        names = {w.name for w in WaypointStore(path).all()}  # loads: the file is whole
        assert {prefix + str(i) for i in range(acked)} <= names
        assert [f for f in os.listdir(tmp_path) if f.endswith(".tmp")] == []


def test_a_new_waypoints_file_is_readable_by_others_and_an_old_one_keeps_its_mode(tmp_path):
    old = os.umask(0o022)
    try:
        store = WaypointStore(str(tmp_path / "waypoints.yaml"))
        store.put(make_waypoint("kitchen", 1.0, 2.0, 0.0))
        assert os.stat(store.path).st_mode & 0o777 == 0o644
        os.chmod(store.path, 0o600)  # the operator's choice is kept
        store.put(make_waypoint("office", 1.0, 2.0, 0.0))
        assert os.stat(store.path).st_mode & 0o777 == 0o600
    finally:
        os.umask(old)
