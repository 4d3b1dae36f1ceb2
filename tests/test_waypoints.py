"""The waypoint store: the seed format, validation, atomic saves, locking, external edits."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flask_move_server import waypoints as wpmod
from flask_move_server.core.errors import BadWaypoint, UnknownWaypoint, WaypointExists, WaypointFileError
from flask_move_server.waypoints import Waypoint, make_waypoint
from flask_move_server.waypoints import store as waypoint_store
from flask_move_server.waypoints.store import WaypointStore

SEED = textwrap.dedent("""\
    waypoints:
      kitchen: [1.23, 4.56, 0.79]     # x [m], y [m], yaw [rad] in the map frame
      office: [5.67, 2.34, -1.57]
      dock: [0.0, 0.0, 0.0]
    """)
SEED_WRITTEN = "waypoints:\n  kitchen: [1.23, 4.56, 0.79]\n  office: [5.67, 2.34, -1.57]\n  dock: [0.0, 0.0, 0.0]\n"


@pytest.fixture
def seed_file(tmp_path):
    path = tmp_path / "waypoints.yaml"
    path.write_text(SEED)
    return path


def test_seed_format_loads_in_order_and_is_written_back_the_same(seed_file):
    store = WaypointStore(seed_file)
    assert [w.name for w in store.all()] == ["kitchen", "office", "dock"]
    assert store.get("office") == Waypoint("office", 5.67, 2.34, -1.57)
    store.put(make_waypoint("dock", 0.0, 0.0, 0.0))  # unchanged value, forces a save
    assert seed_file.read_text() == SEED_WRITTEN
    assert seed_file.with_name("waypoints.yaml.bak").read_text() == SEED


def test_mapping_entries_load_too(tmp_path):
    path = tmp_path / "w.yaml"
    path.write_text("waypoints:\n  lab: {x: 1, y: 2.5, yaw: -0.5}\n")
    assert WaypointStore(path).get("lab") == Waypoint("lab", 1.0, 2.5, -0.5)


def test_missing_file_is_an_empty_store_created_on_first_save(tmp_path):
    path = tmp_path / "new.yaml"
    store = WaypointStore(path)
    assert store.all() == []
    assert store.put(make_waypoint("hall", 1, 2, 3)) is True
    assert path.read_text() == "waypoints:\n  hall: [1.0, 2.0, 3.0]\n"


def test_put_replaces_in_place_and_delete_removes(seed_file):
    store = WaypointStore(seed_file)
    assert store.put(make_waypoint("kitchen", 9, 9, 0)) is False
    assert [w.name for w in store.all()] == ["kitchen", "office", "dock"]
    store.delete("office")
    assert "office" not in seed_file.read_text()
    with pytest.raises(UnknownWaypoint):
        store.delete("office")


def test_unknown_name_suggests_close_names(seed_file):
    with pytest.raises(UnknownWaypoint) as err:
        WaypointStore(seed_file).get("kitchn")
    assert err.value.suggestions == ["kitchen"]
    assert "Did you mean: 'kitchen'" in str(err.value)


@pytest.mark.parametrize("name", [
    "", "a/b", ".", "..", "a..b", "../etc", "tab\there", "nl\n", "nul\x00", "bell\x07", " lead", "trail ",
    "x" * 65, "x" * 300, "semi;colon", "back\\slash", "per%2Fcent", "what?", "hash#tag", "zero\u200bwidth",
    "\u0301accent first", "bidi\u202eoverride", "line\u2028separator", "robot \U0001f916", 42, None,
])
def test_invalid_names_are_refused_and_change_nothing(seed_file, name):
    store = WaypointStore(seed_file)
    before = seed_file.read_bytes()
    with pytest.raises(BadWaypoint):
        store.put(make_waypoint(name, 1, 2, 3))
    assert seed_file.read_bytes() == before


@pytest.mark.parametrize("value", [float("nan"), float("inf"), -float("inf"), "1.0", None, True, [1],
                                   1e308, -1000000.5, pytest.param(10 ** 400, id="int-beyond-float")])
def test_invalid_coordinates_are_refused(value):
    with pytest.raises(BadWaypoint):
        make_waypoint("ok", value, 0, 0)


def test_coordinates_are_bounded_a_yaw_more_tightly():
    assert make_waypoint("edge", 1e6, -1e6, 1e3) == Waypoint("edge", 1e6, -1e6, 1e3)
    with pytest.raises(BadWaypoint, match="yaw must be between -1000 and 1000"):
        make_waypoint("ok", 0, 0, 1001)


@pytest.mark.parametrize("text,problem", [
    ("waypoints: [1, 2]\n", "must map names"),
    ("waypoints:\n  a: [1, 2]\n", "expected [x, y, yaw]"),
    ("waypoints:\n  a: [1, 2, .nan]\n", "finite"),
    ("waypoints:\n  a: [1.0e+308, 2, 3]\n", "line 2: x must be a finite number between -1000000 and 1000000"),
    ("waypoints:\n  '.': [1, 2, 3]\n", "Invalid waypoint name"),
    ("waypoints:\n  a: [1, 2, 3]\n  a: [4, 5, 6]\n", "appears twice"),
    ("waypoints:\n  'a/b': [1, 2, 3]\n", "Invalid waypoint name"),
    ("kitchen: [1, 2, 3]\n", "must hold one mapping"),
    ("waypoints: {a: [1, 2, 3]\n", "not valid YAML"),
])
def test_a_broken_file_is_reported_with_the_reason(tmp_path, text, problem):
    path = tmp_path / "w.yaml"
    path.write_text(text)
    store = WaypointStore(path)  # served as none with the reason, never a server that cannot start
    assert store.all() == [] and problem in store.problem and str(path) in store.problem
    with pytest.raises(WaypointFileError) as err:
        store.put(make_waypoint("porch", 1, 1, 1))
    assert problem in str(err.value)
    assert str(path) in str(err.value)
    assert path.read_text() == text


names = st.from_regex(r"[A-Za-z0-9_-][A-Za-z0-9_. -]{0,62}[A-Za-z0-9_-]", fullmatch=True).filter(
    lambda n: ".." not in n)
coords = st.floats(min_value=-wpmod.POSITION_LIMIT, max_value=wpmod.POSITION_LIMIT, width=64)
yaws = st.floats(min_value=-wpmod.YAW_LIMIT, max_value=wpmod.YAW_LIMIT, width=64)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(names, coords, coords, yaws), max_size=6, unique_by=lambda t: t[0]))
def test_any_valid_waypoints_survive_a_save_and_load(tmp_path_factory, entries):
    path = tmp_path_factory.mktemp("rt") / "w.yaml"
    store = WaypointStore(path)
    wps = [make_waypoint(*e) for e in entries]
    for wp in wps:
        store.put(wp)
    loaded = WaypointStore(path).all()
    assert loaded == wps


def test_numbers_yaml_would_read_as_text_are_written_as_floats(tmp_path):
    path = tmp_path / "w.yaml"
    store = WaypointStore(path)
    store.put(make_waypoint("tiny", 1e-05, -2e-20, 1e-16))  # within the bounds
    assert WaypointStore(path).get("tiny") == Waypoint("tiny", 1e-05, -2e-20, 1e-16)


def test_names_that_yaml_would_misread_are_quoted(tmp_path):
    path = tmp_path / "w.yaml"
    store = WaypointStore(path)
    for name in ("true", "null", "yes", "123", "1.5", "room 2", ".hidden", "-dash"):
        store.put(make_waypoint(name, 1, 2, 3))
    names = ["true", "null", "yes", "123", "1.5", "room 2", ".hidden", "-dash"]
    assert [w.name for w in WaypointStore(path).all()] == names


def test_an_edit_on_disk_is_picked_up_not_overwritten(seed_file):
    store = WaypointStore(seed_file)
    time.sleep(0.01)
    seed_file.write_text(SEED + "  garage: [7.0, 8.0, 0.5]\n")
    assert store.get("garage") == Waypoint("garage", 7.0, 8.0, 0.5)
    store.put(make_waypoint("porch", 1, 1, 1))
    reloaded = WaypointStore(seed_file)
    assert {"garage", "porch", "kitchen"} <= {w.name for w in reloaded.all()}


def test_a_broken_edit_on_disk_keeps_the_last_good_waypoints_and_refuses_writes(seed_file):
    store = WaypointStore(seed_file)
    seed_file.write_text("waypoints:\n  kitchen: [1, 2\n")  # half-typed in an editor
    assert [w.name for w in store.all()] == ["kitchen", "office", "dock"]
    assert "not valid YAML" in store.problem
    with pytest.raises(WaypointFileError) as err:
        store.put(make_waypoint("porch", 1, 1, 1))
    assert "nothing was changed" in str(err.value)
    assert seed_file.read_text() == "waypoints:\n  kitchen: [1, 2\n"  # the user's edit survives
    seed_file.write_text(SEED)
    store.put(make_waypoint("porch", 1, 1, 1))
    assert store.problem is None


def test_save_failure_leaves_store_unchanged_on_full_disk(seed_file, monkeypatch):
    store = WaypointStore(seed_file)

    def disk_full(path, text, backup_text=None):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(waypoint_store.waypoints_file, "atomic_write", disk_full)
    with pytest.raises(WaypointFileError, match="No space left"):
        store.put(make_waypoint("porch", 1, 1, 1))
    assert "porch" not in [w.name for w in store.all()]


WRITER = textwrap.dedent("""\
    import sys
    from flask_move_server.waypoints.store import WaypointStore
    from flask_move_server.waypoints import make_waypoint
    path, prefix, count = sys.argv[1], sys.argv[2], int(sys.argv[3])
    store = WaypointStore(path)
    for i in range(count):
        store.put(make_waypoint("%s%d" % (prefix, i), i, -i, 0.5))
        print("ack", i, flush=True)
    """)


def _writer(path, prefix, count):
    return subprocess.Popen([sys.executable, "-c", WRITER, str(path), prefix, str(count)],
                            stdout=subprocess.PIPE, text=True)


def test_two_processes_writing_at_once_lose_no_update(tmp_path):
    path = tmp_path / "w.yaml"
    writers = [_writer(path, p, 40) for p in ("a", "b")]
    for w in writers:
        assert w.wait(60) == 0
    names = {w.name for w in WaypointStore(path).all()}
    assert names == {"{}{}".format(p, i) for p in "ab" for i in range(40)}


def test_sigkill_mid_stream_keeps_a_valid_file_with_every_acknowledged_write(tmp_path):
    path = tmp_path / "w.yaml"
    for delay in (0.15, 0.3, 0.45):
        proc = _writer(path, "k{}_".format(int(delay * 100)), 100000)
        first = proc.stdout.readline()  # saving has begun (Python's start-up is slow on a loaded machine)
        time.sleep(delay)
        os.kill(proc.pid, signal.SIGKILL)
        lines = [first] + proc.stdout.read().splitlines()
        acked = [line.split()[1] for line in lines if line.startswith("ack")]
        proc.wait()
        assert acked, "the writer acknowledged nothing before the kill"
        saved = {w.name for w in WaypointStore(path).all()}  # loads: the file is valid
        prefix = "k{}_".format(int(delay * 100))
        assert {prefix + i for i in acked} <= saved


def test_rename_keeps_position_and_refuses_clobbering(seed_file):
    store = WaypointStore(seed_file)
    store.rename("office", "study")
    assert [w.name for w in store.all()] == ["kitchen", "study", "dock"]
    with pytest.raises(WaypointExists):
        store.rename("study", "kitchen")
