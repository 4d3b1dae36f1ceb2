"""The map in use from a real /map topic: a real master, a rospy publisher, a real waitress server.

MapSource subscribes with rospy.AnyMsg and decodes the bytes itself (maps/wire.py): the decode
must agree with genpy's, field for field, and the routes must serve what was published.
"""

import io
import math
import struct
from array import array

import pytest
import requests

from flask_move_server.core.errors import MapNotReceived, NoMap
from flask_move_server.core.events import EventBus
from flask_move_server.core.geometry import yaw_to_quaternion
from flask_move_server.maps.catalogue import MapCatalogue
from flask_move_server.maps.service import MapService
from flask_move_server.maps.wire import BadMapMessage, decode
from flask_move_server.web import create_app
from tests.conftest import serve, wait_for
from tests.fake_maps import FakeModes
from tests.fake_robot import FakeRobot


def occupancy_grid(width=6, height=4, value=0, yaw=0.3, frame="map", seq_stamp=(7, 8)):
    import rospy
    from nav_msgs.msg import OccupancyGrid

    msg = OccupancyGrid()
    msg.header.frame_id = frame
    msg.header.stamp = rospy.Time(*seq_stamp)
    msg.info.resolution = 0.05
    msg.info.width, msg.info.height = width, height
    msg.info.origin.position.x, msg.info.origin.position.y = -1.5, 2.25
    q = msg.info.origin.orientation
    q.x, q.y, q.z, q.w = yaw_to_quaternion(yaw)
    cells = [-1] * (width * height)
    cells[width + 1:width + 4] = [value, 100, 50]
    msg.data = array("b", cells)
    return msg


def serialized(msg):
    buff = io.BytesIO()
    msg.serialize(buff)
    return buff.getvalue()


# the decoder, against genpy ------------------------------------------------------------------


def test_the_wire_decoder_reads_what_genpy_writes():
    msg = occupancy_grid()
    header, grid = decode(serialized(msg))
    assert (header.stamp, header.frame_id) == (7 + 8e-9, "map")
    assert (grid.width, grid.height, grid.origin_x, grid.origin_y) == (6, 4, -1.5, 2.25)
    assert grid.resolution == 0.05 and math.isclose(grid.origin_yaw, 0.3, abs_tol=1e-12)
    assert [grid.value(c, r) for r in range(4) for c in range(6)] == list(msg.data)


def test_a_cut_short_or_inconsistent_message_is_refused():
    raw = serialized(occupancy_grid())
    with pytest.raises(BadMapMessage, match="carries"):
        decode(raw[:-3])
    with pytest.raises(BadMapMessage, match="cut short"):
        decode(raw[:30])
    count_at = len(raw) - 24 - 4
    assert struct.unpack_from("<I", raw, count_at) == (24,)
    with pytest.raises(BadMapMessage):
        decode(raw[:count_at] + struct.pack("<I", 23) + raw[count_at + 4:-1])


# the live map over HTTP -----------------------------------------------------------------------


@pytest.fixture
def live(ros_node, unique_name, robot_config, store):
    """A MapSource on a fresh topic, served by a real waitress; and a latched publisher for it."""
    import rospy
    from nav_msgs.msg import OccupancyGrid

    from flask_move_server.ros.map_source import MapSource

    events = EventBus()
    source = MapSource(ros_node, unique_name + "/map", events, event_period=0.3)
    modes = FakeModes(events, mode="mapping")
    service = MapService(MapCatalogue(robot_config.maps_folder()), store, source, modes=modes, events=events,
                         margin=0.0, save_timeout=0.5)
    app = create_app(robot_config, FakeRobot(), store, events=events, maps=service)
    pub = rospy.Publisher(unique_name + "/map", OccupancyGrid, queue_size=1, latch=True)
    with serve(app) as url:
        yield url, pub, source, events, modes
    pub.unregister()
    source.close()


def test_the_published_map_is_served_with_its_crop_and_a_304_until_a_new_one_arrives(live):
    url, pub, source, events, _ = live
    sub = events.subscribe(["map"], replay=False)
    assert requests.get(url + "/map").status_code == 404
    pub.publish(occupancy_grid())
    meta = wait_for(lambda: requests.get(url + "/map").ok and requests.get(url + "/map").json(),
                    message="the map to be served")
    # the known cells: row 1, columns 1..3; no margin: 3 x 1 pixels at 1 cell up and right of the origin
    assert (meta["width"], meta["height"], meta["version"], meta["mode"]) == (3, 1, 1, "mapping")
    cos, sin = math.cos(0.3), math.sin(0.3)
    assert meta["origin"] == pytest.approx([-1.5 + 0.05 * (cos - sin), 2.25 + 0.05 * (sin + cos), 0.3])
    image = requests.get(url + "/map/image")
    assert image.headers["Content-Type"] == "image/png" and image.headers["Cache-Control"] == "no-cache"
    etag = image.headers["ETag"]
    same = requests.get(url + "/map/image", headers={"If-None-Match": etag})
    assert same.status_code == 304 and same.content == b""
    assert sub.next(5) == ("map", {"mode": "mapping", "map": None, "version": 1})

    pub.publish(occupancy_grid(value=100))
    wait_for(lambda: source.version == 2, message="the second map")
    changed = requests.get(url + "/map/image", headers={"If-None-Match": etag})
    assert changed.status_code == 200 and changed.content != image.content and changed.headers["ETag"] != etag
    assert sub.next(5) == ("map", {"mode": "mapping", "map": None, "version": 2})


def test_map_events_are_coalesced_but_the_last_map_is_always_told(live):
    _, pub, source, events, _ = live
    sub = events.subscribe(["map"], replay=False)
    wait_for(lambda: pub.get_num_connections() > 0, message="the subscriber to connect")
    for version, value in enumerate((0, 100, 0, 100), start=1):
        pub.publish(occupancy_grid(value=value))
        wait_for(lambda v=version: source.version == v, message="map {}".format(version))
    seen = []
    while not seen or seen[-1] != 4:
        kind, data = sub.next(5)
        seen.append(data["version"])
    assert seen[0] == 1 and seen == sorted(set(seen))


def test_saving_takes_the_live_map_and_a_silent_topic_is_a_503(live, robot_config):
    url, pub, source, _, _ = live
    r = requests.post(url + "/maps", json={"name": "flat"})
    assert r.status_code == 503 and r.json()["error"] == "no_map_received"
    assert "is mapping running?" in r.json()["message"]
    pub.publish(occupancy_grid())
    r = requests.post(url + "/maps", json={"name": "flat"})
    assert r.status_code == 201, r.text
    saved = MapCatalogue(robot_config.maps_folder()).load("flat")
    assert (saved.width, saved.height) == (6, 4) and saved.value(2, 1) == 100


def test_the_map_is_forgotten_when_its_stack_stops_and_waiters_get_the_next(live):
    url, pub, source, _, modes = live
    pub.publish(occupancy_grid())
    wait_for(lambda: source.version == 1, message="the map")
    version, _ = source.latest(1)
    with pytest.raises(MapNotReceived, match="is mapping running"):
        source.fresh_after(version, 0.05)
    modes.events.publish("mode", {"mode": "navigation", "map": "flat", "state": "stopping"})
    with pytest.raises(NoMap):
        source.current()
    assert requests.get(url + "/map").status_code == 404
    pub.publish(occupancy_grid(value=100))
    version, grid = source.fresh_after(version, 5)
    assert version == 2 and grid.value(1, 1) == 100


def test_a_typed_subscriber_on_the_map_topic_first_does_not_blind_the_source(ros_node, unique_name):
    # rospy shares one subscription per topic and process, with the class of the first subscriber
    import rospy
    from nav_msgs.msg import OccupancyGrid

    from flask_move_server.ros.map_source import MapSource

    topic = unique_name + "/map"
    typed = []
    first = rospy.Subscriber(topic, OccupancyGrid, typed.append)
    source = MapSource(ros_node, topic)
    pub = rospy.Publisher(topic, OccupancyGrid, queue_size=1, latch=True)
    try:
        pub.publish(occupancy_grid(value=100))
        version, grid = source.latest(10)
        assert version == 1 and grid.value(1, 1) == 100 and grid.resolution == 0.05
        wait_for(lambda: typed, message="the typed subscriber's message")
        assert isinstance(typed[0], OccupancyGrid)
    finally:
        pub.unregister()
        first.unregister()
        source.close()
