"""``scan`` events of ``flask-move-server --sim``: the simulated lidar's echoes, in the map frame, on the walls.

A real server process on the demo flat, read as a page reads it (``GET /events``). The points of
a scan must lie on the walls of the world the sim casts its laser in; the server subscribes to
``/scan`` only while a stream is open (asked of the ROS master itself).
"""

import shutil
import xmlrpc.client

import pytest

from flask_move_server.ros.scan import MAX_POINTS
from flask_move_server.sim import occupancy
from tests.conftest import ROOT, ServerProcess, free_port, stop_process, wait_for
from tests.sse import EventReader

DEMO_MAP = str(ROOT) + "/config/maps/demo.yaml"


class ScanSim(ServerProcess):
    """``flask-move-server --sim`` on the demo flat, with its own master."""

    def __init__(self, tmp_path):
        waypoints = tmp_path / "waypoints.yaml"
        shutil.copy(str(ROOT) + "/config/waypoints.demo.yaml", str(waypoints))
        self.master_uri = "http://127.0.0.1:{}".format(free_port())
        env = {"ROS_MASTER_URI": self.master_uri, "ROS_HOME": str(tmp_path), "ROS_LOG_DIR": str(tmp_path / "log"),
               "ROS_IP": "127.0.0.1"}
        super().__init__("--sim", "--port", "0", "--no-mdns", "--waypoints", str(waypoints), env=env,
                         start_timeout=60)
        wait_for(lambda: self.get("/status").json().get("pose") is not None, timeout=30, message="a pose")

    def scan_listeners(self):
        """The nodes subscribed to /scan, as the master knows them."""
        _, _, (_, subscribers, _) = xmlrpc.client.ServerProxy(self.master_uri).getSystemState("/test")
        return [node for topic, nodes in subscribers if topic == "/scan" for node in nodes]


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = ScanSim(tmp_path_factory.mktemp("scan_sim"))
    yield server
    stop_process(server.proc)


def _on_a_wall(world, x, y):
    """True when a cell within one cell of (x, y) is a wall (an echo is cast at a wall cell's edge)."""
    r = world.resolution
    return any((world.value_at(x + dx * r, y + dy * r) or 0) >= 50 for dx in (-1, 0, 1) for dy in (-1, 0, 1))


def test_the_scan_is_told_in_the_map_frame_on_the_walls_only_while_a_page_looks(sim):
    wait_for(lambda: sim.scan_listeners() == [], timeout=10, message="/scan without subscribers")
    world = occupancy.load(DEMO_MAP)
    with EventReader(sim.url, kinds=("scan",)) as reader:
        _, scan = reader.until(lambda kind, data: bool(data["points"]), timeout=20)
        assert sim.scan_listeners() != []
        assert scan["frame"] == "map"
        points = scan["points"]
        assert 50 < len(points) <= MAX_POINTS  # the dock's corner of the living room: walls on every side
        off = [p for p in points if not _on_a_wall(world, *p)]
        assert off == [], "points off the walls of the flat"
    wait_for(lambda: sim.scan_listeners() == [], timeout=10, message="/scan unsubscribed once the page left")
