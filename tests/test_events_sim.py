"""``GET /events`` on ``flask-move-server --sim`` as a phone page meets it: a real server process.

One server for the module, with a single HTTP worker thread, so a stream that took a worker
would be noticed at once. A goal is heard as ``status`` and ``pose`` events; eight open pages
(``server.max_streams``) delay neither ``/stop`` nor any other request; SIGTERM with them open
ends every stream cleanly and the server exits 0 (the last test: it stops the server).
"""

import math
import shutil

import pytest

from tests.conftest import ROOT, ServerProcess, free_port, stop_process, wait_for
from tests.sse import EventReader

FAR = {"x": 8.4, "y": 0.9, "yaw": 0.0}  # the demo flat's kitchen: many seconds of driving


class StreamingSim(ServerProcess):
    """``flask-move-server --sim`` with one worker thread and the default ``max_streams`` (8)."""

    def __init__(self, tmp_path):
        waypoints = tmp_path / "waypoints.yaml"
        shutil.copy(str(ROOT) + "/config/waypoints.demo.yaml", str(waypoints))
        config = tmp_path / "sim.yaml"
        config.write_text("server:\n  threads: 1\nsim:\n  speed_factor: 4.0\n")
        env = {"ROS_MASTER_URI": "http://127.0.0.1:{}".format(free_port()), "ROS_HOME": str(tmp_path),
               "ROS_LOG_DIR": str(tmp_path / "log"), "ROS_IP": "127.0.0.1"}
        super().__init__("--sim", "--config", str(config), "--port", "0", "--no-mdns",
                         "--waypoints", str(waypoints), env=env, start_timeout=60)
        wait_for(lambda: self.get("/health").json().get("move_base") == "ready", timeout=30,
                 message="move_base stand-in ready")
        wait_for(lambda: self.get("/status").json().get("pose") is not None, timeout=30,
                 message="the robot's pose known")  # on a loaded machine tf can come after move_base

    def motors(self):
        motors = self.get("/status").json()["motors"]
        return motors["left"], motors["right"]


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = StreamingSim(tmp_path_factory.mktemp("events_sim"))
    yield server
    stop_process(server.proc)


def _navigation(state):
    return lambda kind, data: kind == "status" and data["navigation"]["state"] == state


def _moved_from(start, distance):
    return lambda kind, data: (kind == "pose" and data is not None
                               and math.hypot(data["x"] - start["x"], data["y"] - start["y"]) > distance)


def test_a_goal_is_heard_as_status_and_pose_events(sim):
    with EventReader(sim.url, kinds=("pose", "status", "estop")) as reader:
        primed = {}  # the latest of each kind the robot tells (its 10 Hz reporter may owe the pose a moment)
        reader.until(lambda kind, data: primed.update({kind: data}) or (
            set(primed) == {"pose", "status", "estop"} and primed["pose"] is not None), timeout=5)
        start = primed["pose"]
        assert start["frame"] == "map" and primed["estop"]["latched"] is False
        assert sim.post("/goto", {"name": "kitchen"}).status_code == 202
        _, active = reader.until(_navigation("active"))
        assert active["navigation"]["target"] == "kitchen"
        reader.until(_moved_from(start, 0.2))
        assert sim.post("/stop").status_code == 200
        reader.until(_navigation("canceled"))


def _open_streams(sim, count):
    """``count`` open streams; a page closed a moment ago holds its place until the server notices."""
    readers = []
    while len(readers) < count:
        reader = wait_for(lambda: _opened(sim), timeout=10, message="a free stream")
        readers.append(reader)
    return readers


def _opened(sim):
    reader = EventReader(sim.url)
    if reader.status_code == 200:
        return reader
    reader.close()
    return None


def test_eight_open_pages_never_delay_stop_nor_take_the_one_worker(sim):
    readers = _open_streams(sim, 8)
    try:
        assert sim.get("/events").status_code == 503  # the ninth
        assert sim.post("/goto", FAR).status_code == 202  # served by the one worker thread
        wait_for(lambda: sim.motors() != (0.0, 0.0), timeout=20, message="the robot to drive")
        answer = sim.post("/stop", timeout=5)
        assert answer.status_code == 200 and answer.json()["canceled_goal"] is True
        wait_for(lambda: sim.motors() == (0.0, 0.0), timeout=5, message="the motors to stop")
        for reader in readers:  # every page heard it
            reader.until(_navigation("canceled"))
    finally:
        for reader in readers:
            reader.close()


def test_sigterm_with_open_streams_ends_them_cleanly_and_exits_0(sim):
    readers = _open_streams(sim, 8)
    for reader in readers:
        reader.until(lambda kind, data: kind == "status")
    assert sim.stop(timeout=10) == 0
    for reader in readers:
        while reader.next() is not None:  # the rest of what was sent, then the stream's clean end
            pass
        assert reader.ended
        reader.close()
