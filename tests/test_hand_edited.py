"""Hand-edited files against a hostile probe (issue 21): an attacker on the Wi-Fi, an owner with a
text editor, a robot losing power.

The waypoints file and the maps folder are real files in a temporary folder; the web layer runs
against tests/fake_robot.py and the real store, catalogue and map service.
"""

import logging
import os

import pytest

from flask_move_server.core.errors import BadRequest, WaypointFileError
from flask_move_server.core.events import EventBus
from flask_move_server.maps.catalogue import MapCatalogue
from flask_move_server.maps.service import MapService
from flask_move_server.modes.targets import Targets
from flask_move_server.waypoints import make_waypoint
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.web import create_app
from tests.fake_maps import FakeMapSource, FakeModes
from tests.fake_robot import FakeRobot
from tests.modes_standin import save_map
from tests.test_waypoints import SEED

DEEP = "waypoints: " + "[" * 5000 + "]" * 5000 + "\n"  # 10 KB: was a RecursionError (a 500, 200 KB logged)
DEEP_MAPPING = "waypoints:\n  kitchen: " + "{a: " * 3000 + "1" + "}" * 3000 + "\n"
BAD_DATE = "waypoints:\n  kitchen: [1, 2, 3]\n  2001-02-30: [1, 2, 3]\n"  # was a ValueError
LIST_KEY = "waypoints:\n  [kitchen]: [1, 2, 3]\n"  # was a TypeError (unhashable)


@pytest.fixture
def seed_file(tmp_path):
    path = tmp_path / "waypoints.yaml"
    path.write_text(SEED)
    return path


@pytest.fixture
def robot():
    return FakeRobot()


@pytest.fixture
def app(robot_config, robot, store):
    events = EventBus()
    modes = FakeModes(events, mode="navigation")  # on the stack's own map: the waypoints file is served
    maps = MapService(MapCatalogue(robot_config.maps_folder()), store, FakeMapSource(), modes=modes, events=events)
    return create_app(robot_config, robot, store, events=events, maps=maps)


def _said(caplog, text):
    return [r for r in caplog.records if text in r.getMessage()]


# 1. any parse failure is a broken file: last good served, said once, never a 500 --------------------------


@pytest.mark.parametrize("text, problem", [
    (DEEP, "nested more than 16 levels deep"),
    (DEEP_MAPPING, "nested more than 16 levels deep"),
    (BAD_DATE, "a value that cannot be read"),
    (LIST_KEY, "a key must be a plain name"),
])
def test_any_parse_failure_keeps_the_last_good_set_said_once_per_version(seed_file, caplog, text, problem):
    store = WaypointStore(seed_file)
    seed_file.write_text(text)
    with caplog.at_level(logging.INFO):
        for _ in range(20):  # a phone polling at 10 Hz
            assert [w.name for w in store.all()] == ["kitchen", "office", "dock"]
            assert problem in store.problem
        for _ in range(3):
            with pytest.raises(WaypointFileError):
                store.put(make_waypoint("porch", 1, 1, 1))
    assert len(_said(caplog, problem)) == 1, [r.getMessage()[:200] for r in caplog.records]
    assert max(len(r.getMessage()) for r in caplog.records) < 1500
    assert seed_file.read_text() == text
    seed_file.write_text(text + "\n")  # another version of the file, as broken: said again, once
    with caplog.at_level(logging.INFO):
        store.all()
        store.all()
    assert len(_said(caplog, problem)) == 2


@pytest.mark.parametrize("text", [DEEP, BAD_DATE, LIST_KEY])
def test_a_broken_file_at_start_up_serves_none_and_says_why_never_a_crash(seed_file, text):
    seed_file.write_text(text)
    store = WaypointStore(seed_file)
    assert store.all() == [] and store.problem
    with pytest.raises(WaypointFileError, match="nothing was changed"):
        store.put(make_waypoint("porch", 1, 1, 1))
    assert seed_file.read_text() == text


def test_deep_nesting_answers_200_on_status_waypoints_and_maps(client, robot_config, caplog):
    path = robot_config.waypoints.file
    save_map(robot_config, "flat", waypoints=DEEP)  # GET /maps counts each map's waypoints
    with open(path, "w") as f:
        f.write(DEEP)
    with caplog.at_level(logging.INFO):
        for _ in range(5):
            status = client.get("/status")
            assert status.status_code == 200
            assert "nested more than 16 levels deep" in status.get_json()["waypoints"]["problem"]
            assert len(status.get_data()) < 5000
            listed = client.get("/waypoints")
            assert listed.status_code == 200 and len(listed.get_json()["waypoints"]) == 3
            maps = client.get("/maps")
            assert maps.status_code == 200 and maps.get_json()["maps"][0]["waypoints"] == 0
        put = client.put("/waypoints/porch", json={"x": 1, "y": 2, "yaw": 0})
    assert put.status_code == 409 and put.get_json()["error"] == "waypoints_file"
    assert len(_said(caplog, "nested more than 16 levels deep")) == 1
    assert sum(len(r.getMessage()) for r in caplog.records) < 5000


# 2. a link planted where the store writes is never written through -----------------------------------------

OUTSIDE = "the owner's file, outside the data folder\n"


@pytest.fixture
def outside(tmp_path):
    folder = tmp_path / "elsewhere"
    folder.mkdir()
    target = folder / "authorized_keys"
    target.write_text(OUTSIDE)
    return target


@pytest.mark.parametrize("planted", ["{}.bak.tmp", "{}.bak"])
def test_a_link_planted_where_a_save_writes_is_replaced_and_its_target_untouched(tmp_path, outside, planted):
    folder = tmp_path / "maps"
    folder.mkdir()
    path = folder / "flat.waypoints.yaml"
    path.write_text(SEED)
    store = WaypointStore(path)
    (folder / planted.format(path.name)).symlink_to(outside)
    store.put(make_waypoint("porch", 1, 1, 1))
    store.put(make_waypoint("garage", 2, 2, 2))
    assert outside.read_text() == OUTSIDE
    assert [w.name for w in WaypointStore(path).all()][-2:] == ["porch", "garage"]
    assert not path.is_symlink() and not (folder / (path.name + ".bak")).is_symlink()
    assert "porch" in (folder / (path.name + ".bak")).read_text()


def test_a_linked_waypoints_file_is_read_through_and_replaced_by_the_first_save(seed_file, outside):
    outside.write_text(SEED)
    seed_file.unlink()
    seed_file.symlink_to(outside)
    store = WaypointStore(seed_file)
    assert len(store.all()) == 3
    store.put(make_waypoint("porch", 1, 1, 1))
    assert outside.read_text() == SEED and not seed_file.is_symlink()
    assert [w.name for w in WaypointStore(seed_file).all()] == ["kitchen", "office", "dock", "porch"]


def test_a_put_through_the_api_never_writes_through_a_planted_temporary(client, robot_config, outside):
    link = robot_config.waypoints.file + ".bak.tmp"
    os.symlink(str(outside), link)
    for name in ("porch", "garage"):
        assert client.put("/waypoints/" + name, json={"x": 1, "y": 2, "yaw": 0}).status_code == 201
    assert outside.read_text() == OUTSIDE
    assert "garage" in open(robot_config.waypoints.file).read()


@pytest.mark.parametrize("exists", [True, False], ids=["to a file", "dangling"])
def test_a_lock_file_that_is_a_link_is_refused_and_nothing_created_or_changed(seed_file, outside, exists):
    target = outside if exists else outside.with_name("new_file")
    store = WaypointStore(seed_file)
    os.symlink(str(target), str(seed_file) + ".lock")
    with pytest.raises(WaypointFileError) as err:
        store.put(make_waypoint("porch", 1, 1, 1))
    assert "symbolic link" in str(err.value) and "rm " in str(err.value)
    assert seed_file.read_text() == SEED
    assert outside.read_text() == OUTSIDE and not outside.with_name("new_file").exists()


def test_temporaries_are_new_files_and_the_bak_keeps_the_files_mode(seed_file):
    os.chmod(str(seed_file), 0o600)
    store = WaypointStore(seed_file)
    store.put(make_waypoint("porch", 1, 1, 1))
    bak = str(seed_file) + ".bak"
    assert os.stat(str(seed_file)).st_mode & 0o777 == 0o600 and os.stat(bak).st_mode & 0o777 == 0o600
    assert [f for f in os.listdir(str(seed_file.parent)) if f.endswith(".tmp")] == []


# 3. errors say the line and what is wrong, never the file's text ----------------------------------------

SECRET = "hunter2-s3cr3t"
SECRET_FILES = [
    pytest.param("waypoints:\n  kitchen: [1, 2, 3]\n  x: [" + SECRET + "\n", 4, id="syntax"),
    pytest.param("waypoints:\n  kitchen: [1, 2, 3]\n  x: !" + SECRET + " [1, 2, 3]\n", 3, id="tag"),
    pytest.param("waypoints:\n  kitchen: [1, 2, 3]\n  x: [1, 2, " + SECRET + "]\n", 3, id="coordinate"),
    pytest.param("waypoints:\n  kitchen: [1, 2, 3]\n  x: " + SECRET + "\n", 3, id="entry"),
    pytest.param("waypoints:\n  kitchen: [1, 2, 3]\n  " + SECRET + "/x: [1, 2, 3]\n", 3, id="name"),
    pytest.param("waypoints:\n  " + SECRET + ": [1, 2, 3]\n  " + SECRET + ": [1, 2, 3]\n", 3, id="twice"),
    pytest.param("waypoints:\n  kitchen: [1, 2, 3]\n  x: \"" + SECRET + "\\q\"\n", 3, id="escape"),
]


@pytest.mark.parametrize("text, line", SECRET_FILES)
def test_a_linked_file_s_broken_line_is_never_quoted_in_answers_or_the_log(client, robot_config, outside, caplog,
                                                                             text, line):
    outside.write_text(text)  # a secret the waypoints file was linked to
    os.unlink(robot_config.waypoints.file)
    os.symlink(str(outside), robot_config.waypoints.file)
    with caplog.at_level(logging.DEBUG):
        problem = client.get("/status").get_json()["waypoints"]["problem"]
        put = client.put("/waypoints/porch", json={"x": 1, "y": 2, "yaw": 0})
    assert put.status_code == 409
    said = [problem, put.get_json()["message"]] + [r.getMessage() for r in caplog.records]
    assert "line {}".format(line) in problem
    assert not [s for s in said if SECRET in s or "s3cr" in s]
    assert outside.read_text() == text


# 4. a name is never echoed back whole -------------------------------------------------------------------

LONG = "k" * 100000
MID = "k" * 8000  # within the body limit


@pytest.mark.parametrize("method, path, body", [
    ("put", "/waypoints/" + LONG, {"x": 1, "y": 2, "yaw": 0}),
    ("get", "/waypoints/" + LONG, None),
    ("delete", "/waypoints/" + LONG, None),
    ("post", "/waypoints/" + LONG, None),
    ("post", "/goto", {"name": MID}),
    ("post", "/goto", {MID: 1}),
    ("post", "/goto", {"name": [MID]}),
    ("put", "/waypoints/ok", {"x": [MID], "y": 2, "yaw": 0}),
    ("post", "/mode", {"mode": MID}),
    ("post", "/mode", {"mode": "navigation", "pose": {MID: 1}}),
    ("post", "/pose", {"name": MID}),
    ("get", "/diagnostics?" + MID + "=1", None),
], ids=lambda v: v[:20] if isinstance(v, str) else None)
def test_a_long_name_is_cut_in_every_error(client, method, path, body):
    answer = getattr(client, method)(path, json=body)
    assert 400 <= answer.status_code < 500
    message = answer.get_json()["message"]
    assert "k" * 81 not in message and len(message) < 400, message[:200]  # names 64, paths 80 characters
    assert "k" * 64 not in message or "\u2026" in message  # said to be cut


def test_an_unknown_mode_is_cut_in_its_error(robot_config):
    with pytest.raises(BadRequest) as err:
        Targets(robot_config, MapCatalogue(robot_config.maps_folder())).of(MID)
    assert len(str(err.value)) < 200 and "\u2026" in str(err.value)


# 6. truncation is judged by structure, not by a final newline ---------------------------------------------


@pytest.mark.parametrize("text", [
    SEED.rstrip("\n"),  # VS Code, Notepad
    SEED.rstrip("\n") + "   # the dock, by the door",
    "waypoints:\n  lab: {x: 1, y: 2.5, yaw: -0.5}",
    "waypoints: {}",
], ids=["seed", "comment", "flow-mapping", "empty-on-purpose"])
def test_a_whole_file_without_a_final_newline_loads(seed_file, text):
    store = WaypointStore(seed_file)
    seed_file.write_text(text)
    assert store.problem is None
    expected = [w.name for w in WaypointStore(seed_file).all()]
    assert [w.name for w in store.all()] == expected
    store.put(make_waypoint("porch", 1, 1, 1))
    assert [w.name for w in WaypointStore(seed_file).all()] == expected + ["porch"]


def test_the_seed_minus_its_last_newline_loads_at_start_up(seed_file):
    WaypointStore(seed_file).put(make_waypoint("dock", 0.0, 0.0, 0.0))  # a .bak of 3: the reference at start
    seed_file.write_text(SEED.rstrip("\n"))
    store = WaypointStore(seed_file)
    assert store.problem is None and [w.name for w in store.all()] == ["kitchen", "office", "dock"]


@pytest.mark.parametrize("text", [
    "waypoints:\n  kitchen: [1.23, 4.56, 0.79]\n  office:\n    x: 5.67\n    y: 2.34\n    yaw: -1.",
    "waypoints:\n  kitchen: [1.23, 4.56, 0.79]\n  office: {x: 5.67, y: 2.34, yaw: -1.",
    "waypoints:\n  kitchen: [1.23, 4.56, 0.79]\n  office: [5.67, 2.34, -1.",
])
def test_a_file_stopping_inside_its_last_entry_is_still_cut_short(seed_file, text):
    store = WaypointStore(seed_file)
    seed_file.write_text(text)
    assert [w.name for w in store.all()] == ["kitchen", "office", "dock"] and store.problem
    with pytest.raises(WaypointFileError):
        store.put(make_waypoint("porch", 1, 1, 1))
    assert seed_file.read_text() == text


# 7. a save drops the owner's comments: said, and the original kept as the .bak -------------------------

COMMENTED = ("# Waypoints of the flat, measured 2026-11-20\n" + SEED
             + "  # the porch is not mapped yet\n")


def test_the_save_that_drops_comments_keeps_the_original_as_bak_and_says_so(seed_file, caplog):
    seed_file.write_text(COMMENTED)
    store = WaypointStore(seed_file)
    with caplog.at_level(logging.WARNING):
        store.put(make_waypoint("porch", 1, 1, 1))
    assert "#" not in seed_file.read_text()
    assert (seed_file.parent / "waypoints.yaml.bak").read_text() == COMMENTED
    said = _said(caplog, "dropped the comments")
    assert len(said) == 1 and str(seed_file) + ".bak" in said[0].getMessage()
    assert "Waypoints of the flat" not in said[0].getMessage()
    caplog.clear()
    with caplog.at_level(logging.WARNING):
        store.put(make_waypoint("garage", 2, 2, 2))  # nothing left to drop: nothing said
    assert not _said(caplog, "dropped the comments")


def test_a_put_over_the_api_on_a_commented_file_keeps_it_as_bak(client, robot_config, caplog):
    with open(robot_config.waypoints.file, "w") as f:
        f.write(COMMENTED)
    with caplog.at_level(logging.WARNING):
        assert client.put("/waypoints/porch", json={"x": 1, "y": 2, "yaw": 0}).status_code == 201
    assert open(robot_config.waypoints.file + ".bak").read() == COMMENTED
    assert len(_said(caplog, "dropped the comments")) == 1


def test_nesting_is_counted_before_yaml_reads_the_text_and_brackets_in_names_or_comments_are_not():
    """Thousands of brackets are refused by a count over the brackets alone: PyYAML's pure-Python
    scanner looked ahead over all of them first (125 ms for 10 KB, the drive loop held up)."""
    from flask_move_server.config import guarded_yaml

    deep = "waypoints:\n  k: " + "[" * 5000 + "]" * 5000 + "\n"
    with pytest.raises(guarded_yaml.Unreadable, match=r"^line 2: nested more than 16 levels deep$"):
        guarded_yaml.load(deep)
    quoted = 'waypoints:\n  "' + "[" * 40 + 'x": [1, 2, 3]  # ' + "{" * 40 + "\n"
    assert guarded_yaml.load(quoted).data == {"waypoints": {"[" * 40 + "x": [1, 2, 3]}}
