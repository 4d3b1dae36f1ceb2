"""The sim's map server handing /map over to the next one, and ``GET /map`` after every switch.

The sim publishes ``/map`` in the server's own process (``sim/map_server.py``, ``sim/mapping.py``),
and the server's map reader (``ros/map_source.py``) subscribes to it there. A switch takes the old
publisher away and registers a new one on the same topic, from the same node URI. If the reader's
receive thread was still busy with the old map then (a slow moment on a loaded robot; below, a
listener of ``map`` events that holds it), rospy found its old connection to that URI still listed,
said "already connected" and never connected to the new publisher: its latched map never came, and
``GET /map`` answered 404 ("no map in use" on the page) until the server restarted. Real master,
real rospy, real parts; then a real ``flask-move-server --sim`` switched back and forth.
"""

import threading

import pytest
import requests

from flask_move_server.core.events import EventBus
from flask_move_server.ros.map_source import MapSource
from flask_move_server.sim.map_server import MapServerStandIn
from flask_move_server.sim.occupancy import OccupancyMap
from tests.conftest import ServerProcess, free_port, stop_process, wait_for

DEMO = {"mode": "navigation", "map": "demo"}
FLAT = {"mode": "navigation", "map": "flat"}
MAPPING = {"mode": "mapping"}
ROUNDS = 3


def grid(width):
    return OccupancyMap(width=width, height=3, resolution=0.05, origin_x=0.0, origin_y=0.0,
                        cells=[0] * (width * 3), source="{} cells wide".format(width))


def held_width(source):
    try:
        return source.current()[1].width
    except LookupError:
        return None


def test_the_next_map_server_is_heard_while_the_reader_is_still_busy_with_the_last_map(ros_node, unique_name):
    events = EventBus()
    free = threading.Event()
    source = MapSource(ros_node, topic=unique_name, events=events, event_period=0.0)
    events.listen("map", lambda _: free.wait(10))  # holds the receive thread of each map that arrives
    served = [MapServerStandIn(ros_node, grid(4), "map", unique_name)]
    try:
        wait_for(lambda: held_width(source) == 4, timeout=10, message="the first map")
        for width in (5, 6, 7):  # a switch: the old map server goes, the next one comes, on the same topic
            served.pop().close()
            served.append(MapServerStandIn(ros_node, grid(width), "map", unique_name))
            wait_for(lambda width=width: held_width(source) == width, timeout=10,
                     message="the {}-cell map".format(width))
    finally:
        free.set()
        for server in served:
            server.close()
        source.close()


# a real --sim server ----------------------------------------------------------------------------


class SwitchingSim(ServerProcess):
    """``flask-move-server --sim`` on its own master, with its files in ``folder``."""

    def __init__(self, folder):
        (folder / "sim.yaml").write_text("sim:\n  speed_factor: 4.0\n")
        (folder / "waypoints.yaml").write_text("waypoints:\n  dock: [0.0, 0.0, 0.0]\n")
        env = {"ROS_MASTER_URI": "http://127.0.0.1:{}".format(free_port()), "ROS_HOME": str(folder),
               "ROS_LOG_DIR": str(folder / "log"), "ROS_IP": "127.0.0.1"}
        super().__init__("--sim", "--config", str(folder / "sim.yaml"), "--host", "127.0.0.1", "--port", "0",
                         "--no-mdns", "--waypoints", str(folder / "waypoints.yaml"), env=env, start_timeout=60)
        wait_for(lambda: self.get("/mode").json()["state"] == "running", timeout=60, message="the start-up mode")

    def switch(self, body):
        r = requests.post(self.url + "/mode", json=dict(body, wait=60), timeout=70)
        assert r.status_code == 200, r.text

    def live_map(self, after):
        """``GET /map`` once it answers 200 (a switch's map may take a moment to arrive), else fail."""
        def answered():
            r = requests.get(self.url + "/map", timeout=10)
            return r.json() if r.status_code == 200 else None

        return wait_for(answered, timeout=10, message="GET /map to answer 200 after {}".format(after))


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = SwitchingSim(tmp_path_factory.mktemp("map_handover"))
    yield server
    stop_process(server.proc)


def shape(meta):
    return meta["width"], meta["height"], meta["origin"]


def test_after_every_switch_get_map_answers_with_the_map_switched_to(sim):
    demo = sim.live_map("start-up")
    sim.switch(MAPPING)
    sim.live_map(MAPPING)
    assert requests.post(sim.url + "/maps", json={"name": "flat"}, timeout=30).status_code in (200, 201)
    sim.switch(FLAT)
    flat = sim.live_map(FLAT)
    assert shape(flat) != shape(demo)  # the saved map is told from the demo's by its shape
    for _ in range(ROUNDS):
        for body, wanted in ((DEMO, demo), (MAPPING, None), (DEMO, demo), (FLAT, flat), (DEMO, demo)):
            sim.switch(body)
            now = sim.live_map(body)
            assert (now["mode"], now["map"]) == (body["mode"], body.get("map"))  # the demo's own map by its name
            if wanted is not None:
                assert shape(now) == shape(wanted), body
