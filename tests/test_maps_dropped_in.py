"""The maps folder as users meet it: files dropped in by hand, files copied off the robot.

A map YAML's ``image`` may name any file: a clear answer, never a hang. Saved files are
readable as the umask allows, like map_saver's. The real web app, maps folder and
waypoint store on temporary files; the mode manager and the live map are the
stand-ins of tests/fake_maps.py.
"""

import os
import re
import stat
import subprocess
import sys
import threading
import time

import pytest

from flask_move_server.core.errors import WaypointFileError
from flask_move_server.core.events import EventBus
from flask_move_server.maps import render
from flask_move_server.maps.catalogue import MapCatalogue
from flask_move_server.maps.service import MapService
from flask_move_server.modes import state_file
from flask_move_server.waypoints import make_waypoint
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.web import create_app
from tests.fake_maps import FakeMapSource, FakeModes
from tests.fake_robot import FakeRobot
from tests.test_maps_web import room


@pytest.fixture
def folder(robot_config):
    path = robot_config.maps_folder()
    os.makedirs(path, exist_ok=True)
    return path


@pytest.fixture
def mode():
    return "idle"


@pytest.fixture
def client(robot_config, store, folder, mode):
    events = EventBus()
    service = MapService(MapCatalogue(folder), store, FakeMapSource(room()), modes=FakeModes(events, mode=mode),
                         events=events)
    return create_app(robot_config, FakeRobot(), store, events=events, maps=service).test_client()


def drop_map(folder, name, image):
    with open(os.path.join(folder, name + ".yaml"), "w") as f:
        f.write("image: {}\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\n".format(image))


def test_a_map_whose_image_is_a_fifo_is_listed_with_its_problem_not_a_stuck_worker(client, folder):
    fifo = os.path.join(folder, "pipe.pgm")
    os.mkfifo(fifo)
    drop_map(folder, "pipe", "pipe.pgm")
    answers = {}

    def ask():
        answers["list"] = client.get("/maps")
        answers["image"] = client.get("/maps/pipe/image")

    asking = threading.Thread(target=ask, daemon=True)
    asking.start()
    asking.join(10)
    if asking.is_alive():  # free the stuck reader before failing: open the FIFO's other end
        os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        pytest.fail("reading a map whose image is a FIFO never answered")
    listed = answers["list"].get_json()["maps"]
    assert listed[0]["name"] == "pipe" and "not a regular file" in listed[0]["problem"]
    image = answers["image"]
    assert image.status_code == 503 and "not a regular file" in image.get_json()["message"]


def test_an_image_declaring_more_cells_than_a_map_may_have_is_refused_unread(client, folder):
    with open(os.path.join(folder, "vast.pgm"), "wb") as f:
        f.write(b"P5\n7000 7000\n255\n")
        f.truncate(17 + 7000 * 7000)  # sparse: a whole image, costing no disk
    drop_map(folder, "vast", "vast.pgm")
    answer = client.get("/maps/vast/image")
    assert answer.status_code == 503, answer.status_code
    assert "7000 x 7000" in answer.get_json()["message"]
    assert "7000 x 7000" in client.get("/maps/vast").get_json()["problem"]


def test_a_map_pointing_outside_the_folder_is_refused_unread(client, folder):
    drop_map(folder, "passwd", "/etc/passwd")
    answer = client.get("/maps/passwd/image")
    assert answer.status_code == 503 and "outside the map's folder" in answer.get_json()["message"]


@pytest.fixture
def umask_0027():
    old = os.umask(0o027)  # the systemd unit's UMask
    yield
    os.umask(old)


@pytest.mark.parametrize("mode", ["mapping"])
def test_a_saved_map_and_its_waypoints_are_readable_by_the_group_as_the_umask_allows(client, folder, umask_0027):
    assert client.put("/waypoints/desk", json={"x": 1, "y": 1, "yaw": 0}).status_code == 201  # marked while mapping
    assert client.post("/maps", json={"name": "flat"}).status_code == 201
    modes = {f: stat.S_IMODE(os.stat(os.path.join(folder, f)).st_mode) for f in os.listdir(folder)}
    assert modes == {"flat.yaml": 0o640, "flat.pgm": 0o640, "flat.waypoints.yaml": 0o640}


def test_the_restore_command_for_a_broken_waypoints_file_of_a_map_with_a_space_works_in_a_shell(tmp_path):
    path = tmp_path / "my flat.waypoints.yaml"
    path.write_text("waypoints:\n  dock: [0.0, 0.0, 0.0]\n")
    store = WaypointStore(str(path))
    store.put(make_waypoint("porch", 1, 1, 1))  # the .bak: the dock alone
    path.write_text("waypoints: [[[\n")  # a bad hand edit
    with pytest.raises(WaypointFileError) as err:
        store.put(make_waypoint("hall", 2, 2, 0))
    command = re.search(r"\((cp .*)\)", str(err.value)).group(1)
    subprocess.run(["sh", "-c", command], check=True, cwd=str(tmp_path / ".."))
    assert "dock" in path.read_text() and "[[[" not in path.read_text()


def test_no_restore_command_is_offered_without_a_backup(tmp_path):
    path = tmp_path / "my flat.waypoints.yaml"
    path.write_text("waypoints:\n  dock: [0.0, 0.0, 0.0]\n")
    store = WaypointStore(str(path))
    path.write_text("waypoints: [[[\n")
    with pytest.raises(WaypointFileError) as err:
        store.put(make_waypoint("hall", 2, 2, 0))
    assert "cp " not in str(err.value) and "waypoints: {}" in str(err.value)


@pytest.mark.parametrize("method, path", [
    ("GET", "/maps/a%2Fb"), ("DELETE", "/maps/..%2Fwaypoints"), ("PATCH", "/maps/a%0Ab"), ("GET", "/maps/a%2Fb/image"),
])
def test_a_slash_or_line_break_in_a_map_name_is_a_bad_map_name_not_no_such_endpoint(client, method, path):
    answer = client.open(path, method=method, json={"name": "new"} if method == "PATCH" else None)
    assert answer.status_code == 400 and answer.get_json()["error"] == "bad_map_name", answer.get_json()


def test_a_map_name_slash_image_still_serves_the_image(client, folder):
    with open(os.path.join(folder, "flat.pgm"), "wb") as f:
        f.write(b"P5\n2 2\n255\n" + bytes([254, 0, 205, 254]))
    drop_map(folder, "flat", "flat.pgm")
    assert client.get("/maps/flat/image").mimetype == "image/png"
    assert client.get("/maps/flat").get_json()["width"] == 2


def _in_time(work, seconds=10):
    """``work()``'s result, or None if it did not answer within ``seconds`` (the thread is left hanging)."""
    answers = []
    thread = threading.Thread(target=lambda: answers.append(work()), daemon=True)
    thread.start()
    thread.join(seconds)
    return answers[0] if answers else None


def _unblock(fifo):
    os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))  # a stuck reader (without the fix) gets EOF


def test_a_maps_waypoints_file_that_is_a_fifo_neither_hangs_the_list_nor_the_mode_state(client, folder, tmp_path):
    with open(os.path.join(folder, "flat.pgm"), "wb") as f:
        f.write(b"P5\n2 2\n255\n" + bytes([254, 0, 205, 254]))
    drop_map(folder, "flat", "flat.pgm")
    fifo = os.path.join(folder, "flat.waypoints.yaml")
    os.mkfifo(fifo)
    listed = _in_time(lambda: client.get("/maps"))
    if listed is None:
        _unblock(fifo)
        pytest.fail("GET /maps never answered: it read a FIFO")
    assert listed.get_json()["maps"][0]["waypoints"] == 0
    state = str(tmp_path / "mode.json")
    os.mkfifo(state)
    remembered = _in_time(lambda: state_file.load(state))
    if remembered is None:
        _unblock(state)
        pytest.fail("reading the mode state file never answered: it read a FIFO")
    assert remembered == (None, "cannot read {}: not a regular file".format(state))


def test_a_mode_state_file_linked_to_dev_zero_is_refused_not_read_forever(tmp_path):
    state = tmp_path / "mode.json"
    state.symlink_to("/dev/zero")
    # capped at 2 GiB: without the fix this reads until MemoryError, never the machine's memory
    code = ("import resource; resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))\n"
            "from flask_move_server.modes import state_file; print(state_file.load({!r}))".format(str(state)))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-300:]
    assert "not a regular file" in done.stdout


def test_images_asked_for_at_once_are_loaded_and_rendered_one_at_a_time_and_once_per_version():
    cache, other = render.ImageCache(), render.ImageCache()
    inside, most, made = [0], [0], []
    lock = threading.Lock()

    def make(version):
        def work():
            with lock:
                inside[0] += 1
                most[0] = max(most[0], inside[0])
                made.append(version)
            time.sleep(0.2)  # a big map's load and render; the others ask meanwhile
            with lock:
                inside[0] -= 1
            return version
        return work

    asks = [(cache, "v1")] * 6 + [(other, "v2")] * 2
    threads = [threading.Thread(target=lambda c=c, v=v: c.image(v, make(v))) for c, v in asks]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(30)
    assert sorted(made) == ["v1", "v2"] and most[0] == 1
    assert cache.get("v1") == "v1" and other.get("v2") == "v2"
