"""Map files as a hostile hand could drop them into the maps folder (issue 21): an alias bomb,
megabytes of YAML, thousands of brackets, a value kilobytes long. Each is a broken map listed with a
short reason, parsed once per version of its file, never a flood, a stall or a 500. The real web app,
maps folder and waypoint store on temporary files; the mode manager and the live map are the
stand-ins of tests/fake_maps.py, the stack the stand-in of tests/modes_standin.py.
"""

import logging
import os

import pytest

from flask_move_server import config as config_mod
from flask_move_server.core.errors import MapFileError, StackFailed
from flask_move_server.core.events import EventBus
from flask_move_server.maps.catalogue import MapCatalogue
from flask_move_server.maps.service import MapService
from flask_move_server.modes.manager import ModeManager
from flask_move_server.web import create_app
from tests.fake_maps import FakeMapSource, FakeModes
from tests.fake_robot import FakeRobot
from tests.modes_standin import StandInStack, save_map
from tests.test_maps_web import room

SMALL_PGM = b"P5\n2 2\n255\n" + bytes([254, 0, 205, 254])


@pytest.fixture
def folder(robot_config):
    path = robot_config.maps_folder()
    os.makedirs(path, exist_ok=True)
    with open(os.path.join(path, "b.pgm"), "wb") as f:
        f.write(SMALL_PGM)
    return path


@pytest.fixture
def client(robot_config, store, folder):
    events = EventBus()
    service = MapService(MapCatalogue(folder), store, FakeMapSource(room()), modes=FakeModes(events), events=events)
    return create_app(robot_config, FakeRobot(), store, events=events, maps=service).test_client()


def alias_bomb():
    """398 bytes of YAML whose origin is 9^8 strings once its aliases are expanded."""
    lines = ["image: b.pgm", "resolution: 0.05", 'a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for prev, name in zip("abcdefg", "bcdefgh"):
        lines.append("{0}: &{0} [{1}]".format(name, ",".join(["*" + prev] * 9)))
    return "\n".join(lines + ["origin: [*h, *h, *h]"]) + "\n"


def drop(folder, name, text):
    with open(os.path.join(folder, name + ".yaml"), "w") as f:
        f.write(text)


def listed(client):
    answer = client.get("/maps")
    assert answer.status_code == 200, answer.data[:300]
    assert len(answer.data) < 4000, "GET /maps answered {} bytes".format(len(answer.data))
    return {m["name"]: m for m in answer.get_json()["maps"]}


def test_an_alias_bomb_is_a_broken_map_listed_in_a_few_bytes(client, folder):
    drop(folder, "bomb", alias_bomb())
    drop(folder, "good", "image: b.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    maps = listed(client)
    assert "anchors and aliases" in maps["bomb"]["problem"] and maps["bomb"]["width"] is None
    assert maps["good"]["width"] == 2 and "problem" not in maps["good"]
    answer = client.get("/maps/bomb/image")
    assert answer.status_code == 503 and len(answer.data) < 2000


def test_a_map_yaml_past_the_size_cap_is_refused_unparsed(client, folder):
    drop(folder, "big", "image: b.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnotes: [{}]\n".format(
        ",".join(["1.0"] * 30000)))  # ~120 KB
    assert "larger than the 65536 bytes" in listed(client)["big"]["problem"]


def test_thousands_of_brackets_are_a_broken_map_logged_once_per_version_never_a_500(client, folder, caplog):
    drop(folder, "deep", "image: b.pgm\nresolution: 0.05\norigin: " + "[" * 5000 + "]" * 5000 + "\n")
    with caplog.at_level(logging.WARNING, logger="flask_move_server.maps.catalogue"):
        for _ in range(3):
            assert "nest" in listed(client)["deep"]["problem"]
        assert client.get("/maps/deep").status_code == 200
    assert len([r for r in caplog.records if "'deep'" in r.getMessage()]) == 1
    drop(folder, "deep", "image: b.pgm\nresolution: 0.05\norigin: " + "[" * 40 + "]" * 40 + "\n")  # a new version
    with caplog.at_level(logging.WARNING, logger="flask_move_server.maps.catalogue"):
        assert "nested deeper than 32" in listed(client)["deep"]["problem"]
    assert len([r for r in caplog.records if "'deep'" in r.getMessage()]) == 2


@pytest.mark.parametrize("key, value", [
    ("origin", "[0.0, 0.0, {}]".format(["lol"] * 5000)), ("origin", '[0.0, 0.0, "{}"]'.format("9" * 20000)),
    ("image", "x" * 20000), ("resolution", "'{}'".format("r" * 20000)), ("mode", "m" * 20000),
    ("negate", "9" * 20000),  # more digits than Python turns into an int: refused by the reader, key unnamed
])
def test_a_long_bad_value_is_quoted_in_a_short_excerpt(client, folder, key, value):
    fields = {"image": "b.pgm", "resolution": "0.05", "origin": "[0.0, 0.0, 0.0]", key: value}
    drop(folder, "long", "".join("{}: {}\n".format(k, v) for k, v in fields.items()))
    problem = listed(client)["long"]["problem"]
    assert len(problem) < len(folder) + 300, problem
    assert key in problem or "cannot be read (ValueError)" in problem


@pytest.mark.parametrize("text", [
    "image: b.pgm\nsecret: !!python/object:hunter2 x\n",  # PyYAML's message quotes the tag
    "image: b.pgm\nsecret: \"hunter2\n",  # unterminated
    "image: b.pgm\nsecret: [hunter2\n",
])
def test_a_map_yaml_that_does_not_parse_is_described_without_its_text(client, folder, text):
    drop(folder, "bad", text)
    problem = listed(client)["bad"]["problem"]
    assert "hunter2" not in problem and "line" in problem, problem


def test_an_unchanged_map_is_parsed_once_however_often_it_is_listed(client, folder, monkeypatch):
    from flask_move_server.sim import occupancy

    reads = []
    real = occupancy.read_meta
    monkeypatch.setattr(occupancy, "read_meta", lambda path, **kw: reads.append(path) or real(path, **kw))
    drop(folder, "flat", "image: b.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    for _ in range(5):
        assert listed(client)["flat"]["width"] == 2
    assert len(reads) == 1
    drop(folder, "flat", "image: b.pgm\nresolution: 0.10\norigin: [0.0, 0.0, 0.0]\n")
    os.utime(os.path.join(folder, "flat.yaml"), ns=(1, 1))  # a new version even on a coarse clock
    assert listed(client)["flat"]["resolution"] == 0.10 and len(reads) == 2
    with open(os.path.join(folder, "b.pgm"), "wb") as f:  # the image alone changed
        f.write(b"P5\n3 1\n255\n" + bytes(3))
    assert listed(client)["flat"]["width"] == 3 and len(reads) == 3


@pytest.fixture
def cfg(tmp_path):
    c = config_mod.Config()
    c.waypoints.file = str(tmp_path / "waypoints.yaml")
    c.modes.stack = "roslaunch"
    return c


def test_a_switch_to_a_broken_map_is_refused_before_anything_stops_in_a_short_message(cfg):
    stack, bus, seen = StandInStack(), EventBus(), []
    bus.listen("mode", seen.append)
    modes = ModeManager(cfg, stack, bus)
    try:
        save_map(cfg, "flat")
        drop(cfg.maps_folder(), "bomb", alias_bomb())
        modes.switch("navigation", "flat")
        assert modes.wait(5)
        with pytest.raises(MapFileError, match="anchors and aliases") as refused:
            modes.switch("navigation", "bomb")
        assert len(str(refused.value)) < 600
        assert modes.status()["map"] == "flat" and modes.status()["state"] == "running"
        assert stack.starts() == [("navigation", os.path.join(cfg.maps_folder(), "flat.yaml"))]
    finally:
        modes.close()


def test_a_stack_failing_with_a_huge_message_carries_a_bounded_one_in_the_mode_and_its_events(cfg):
    stack, bus, seen = StandInStack(), EventBus(), []
    bus.listen("mode", seen.append)
    modes = ModeManager(cfg, stack, bus)
    try:
        stack.failures.append("map_server died: origin: must be [x, y, yaw], got " + "['lol', " * 200000)
        modes.switch("mapping")
        with pytest.raises(StackFailed) as failed:
            modes.wait(5)
        assert len(str(failed.value)) <= 1000 and str(failed.value).startswith("map_server died")
        assert modes.status()["state"] == "failed" and len(modes.status()["message"]) <= 1000
        assert seen and all(len(e["message"]) <= 1000 for e in seen)
    finally:
        modes.close()


# the image (and the YAML) stay in the maps folder ---------------------------------------------


def test_an_image_named_outside_the_folder_is_refused_unread(client, folder, tmp_path):
    with open(str(tmp_path / "secret.pgm"), "wb") as f:  # a real image, one level above the folder
        f.write(SMALL_PGM)
    drop(folder, "up", "image: ../secret.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    drop(folder, "abs", "image: {}\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n".format(tmp_path / "secret.pgm"))
    drop(folder, "shadow", "image: /etc/shadow\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    maps = listed(client)
    for name in ("up", "abs", "shadow"):
        assert "outside the map's folder" in maps[name]["problem"], maps[name]
        answer = client.get("/maps/{}/image".format(name))
        assert answer.status_code == 503 and "outside the map's folder" in answer.get_json()["message"]


def test_a_symlink_in_the_folder_is_followed_only_while_it_stays_in_the_folder(client, folder, tmp_path):
    os.makedirs(os.path.join(folder, "images"))
    os.symlink(os.path.join(folder, "b.pgm"), os.path.join(folder, "images", "inside.pgm"))
    with open(str(tmp_path / "outside.pgm"), "wb") as f:
        f.write(SMALL_PGM)
    os.symlink(str(tmp_path / "outside.pgm"), os.path.join(folder, "outside.pgm"))
    drop(folder, "in", "image: images/inside.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    drop(folder, "out", "image: outside.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    with open(str(tmp_path / "elsewhere.yaml"), "w") as f:
        f.write("image: b.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n")
    os.symlink(str(tmp_path / "elsewhere.yaml"), os.path.join(folder, "linked.yaml"))
    maps = listed(client)
    assert maps["in"]["width"] == 2 and client.get("/maps/in/image").status_code == 200
    assert "outside the map's folder" in maps["out"]["problem"]
    assert "symbolic link to a file outside the maps folder" in maps["linked"]["problem"]
    answer = client.get("/maps/linked/image")
    assert answer.status_code == 503 and "symbolic link" in answer.get_json()["message"]


def test_post_mode_to_a_broken_map_answers_503_map_file_and_the_mode_stays_small(robot_config, store):
    stack, bus, seen = StandInStack(), EventBus(), []
    bus.listen("mode", seen.append)
    modes = ModeManager(robot_config, stack, bus)
    client = create_app(robot_config, FakeRobot(), store, events=bus, modes=modes).test_client()
    try:
        os.makedirs(robot_config.maps_folder())
        drop(robot_config.maps_folder(), "bomb", alias_bomb())
        answer = client.post("/mode", json={"mode": "navigation", "map": "bomb"})
        body = answer.get_json()
        assert answer.status_code == 503 and body["error"] == "map_file", body
        assert "anchors and aliases" in body["message"] and len(answer.data) < 1000
        assert stack.calls == [] and len(client.get("/mode").data) < 1000 and len(client.get("/status").data) < 4000
        assert seen == []
    finally:
        modes.close()
