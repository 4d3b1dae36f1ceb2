"""``GET /events`` over the product's HTTP server (http/server.py), real sockets, the fake robot.

What a page reading the stream notices: the latest state at once on connect, each change as it
comes, heartbeats on a quiet stream, a JSON 503 past ``server.max_streams``, a 401 without the
token; and what the robot's owner would notice: a reader that stops reading costs a bounded
amount of memory, and a page that goes away gives its place back.
"""

import contextlib
import socket
import threading
import time

import pytest
import requests

from flask_move_server.core.errors import TooManyStreams
from flask_move_server.http.connection import STREAM_BACKLOG
from flask_move_server.web import create_app
from flask_move_server.web.events import StreamGate
from tests.conftest import hardened, wait_for
from tests.fake_robot import FakeRobot
from tests.sse import EventReader

# What these tests publish themselves; the app's own maps service also tells the waypoints it serves.
ROBOT_STATE = ("pose", "status", "estop", "mode")  # the clock events come too; most tests skip them

TOKEN = "stream-test-token"


@contextlib.contextmanager
def _serve(robot_config, store, bus, token=None, **gate):
    """The app on the product's server, whose loop sleeps long when nothing wakes it.

    Waitress's loop wakes once a second by itself; here an event only arrives before the
    reader's 10 s timeout if it is sent when written, not when the loop next wakes.
    """
    app = create_app(robot_config, FakeRobot(), store, token=token, events=bus)
    if gate:
        app.extensions["flask_move_server"]["streams"] = StreamGate(**gate)
    with hardened(app, robot_config.server, loop_timeout=60) as served:
        yield served


def test_a_new_stream_gets_the_latest_state_at_once_then_each_change(robot_config, store, bus):
    bus.publish("estop", {"latched": False, "source": None, "since": None})
    bus.publish("pose", {"x": 1.0, "y": 2.0, "yaw": 0.0, "frame": "map", "age": 0.0})
    with _serve(robot_config, store, bus) as (_, url), EventReader(url, kinds=ROBOT_STATE) as reader:
        assert reader.status_code == 200
        assert reader.response.headers["Content-Type"].startswith("text/event-stream")
        assert reader.response.headers["Cache-Control"] == "no-store"
        assert reader.next() == ("estop", {"latched": False, "source": None, "since": None})
        assert reader.next()[1]["x"] == 1.0
        assert reader.retry == 2000
        bus.publish("pose", {"x": 1.5, "y": 2.0, "yaw": 0.0, "frame": "map", "age": 0.0})
        assert reader.next() == ("pose", {"x": 1.5, "y": 2.0, "yaw": 0.0, "frame": "map", "age": 0.0})


def test_a_quiet_stream_tells_the_robot_clock_every_heartbeat(robot_config, store, bus):
    """A page tells a silent link from a quiet robot by these, and learns the clock valid_until is read on."""
    bus.publish("mode", {"mode": "idle"})
    with _serve(robot_config, store, bus, max_streams=2, heartbeat=0.1) as (_, url), \
            EventReader(url, kinds=ROBOT_STATE + ("clock",)) as reader:
        kind, first = reader.next()
        assert kind == "clock" and abs(first["now"] - time.monotonic()) < 1.0, "the robot's own monotonic clock"
        assert reader.next() == ("mode", {"mode": "idle"})
        assert reader.next()[0] == "clock"
        kind, later = reader.next()
        assert kind == "clock" and later["now"] > first["now"]


def test_a_busy_stream_still_tells_the_clock(robot_config, store, bus):
    """Poses every 20 ms do not crowd the clock out: it comes every heartbeat whatever else is sent."""
    with _serve(robot_config, store, bus, max_streams=2, heartbeat=0.3) as (_, url), \
            EventReader(url, kinds=("pose", "clock")) as reader:
        stop = threading.Event()

        def chatter():
            while not stop.wait(0.02):
                bus.publish("pose", {"x": time.monotonic(), "y": 0.0, "yaw": 0.0, "frame": "map", "age": 0.0})
        talker = threading.Thread(target=chatter, daemon=True)
        talker.start()
        try:
            clocks, started = [], time.monotonic()
            while len(clocks) < 4 and time.monotonic() - started < 10:
                kind, data = reader.next()
                if kind == "clock":
                    clocks.append(data["now"])
        finally:
            stop.set()
            talker.join()
        assert len(clocks) == 4, "a clock event at least every heartbeat while poses stream"


def test_one_stream_more_than_max_streams_is_a_json_503_and_a_closed_one_gives_its_place_back(
        robot_config, store, bus):
    robot_config.server.max_streams = 2
    with _serve(robot_config, store, bus) as (server, url):
        first, second = EventReader(url, kinds=ROBOT_STATE), EventReader(url, kinds=ROBOT_STATE)
        third = requests.get(url + "/events", timeout=10)
        assert third.status_code == 503
        assert third.headers["Content-Type"] == "application/json; charset=utf-8"
        assert third.json()["error"] == "too_many_streams"
        first.close()  # the page went away: noticed without waiting for a heartbeat
        wait_for(lambda: _opens(url), timeout=10, message="the closed stream's place to be free again")
        second.close()


def _opens(url):
    with EventReader(url, kinds=ROBOT_STATE) as reader:
        return reader.status_code == 200


def test_a_token_is_needed_when_the_robot_has_one(robot_config, store, bus):
    with _serve(robot_config, store, bus, token=TOKEN) as (_, url):
        refused = requests.get(url + "/events", timeout=10)
        assert refused.status_code == 401 and refused.json()["error"] == "unauthorized"
        bus.publish("estop", {"latched": True, "source": "api", "since": None})
        with EventReader(url, headers={"Authorization": "Bearer " + TOKEN}, kinds=ROBOT_STATE) as reader:
            assert reader.next()[0] == "estop"


def test_a_reader_that_stops_reading_holds_a_bounded_backlog(robot_config, store, bus):
    padding = "x" * 20000
    with _serve(robot_config, store, bus) as (server, url):
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        sock.connect(("127.0.0.1", int(server.effective_port)))
        sock.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        sock.recv(100)  # the stream began; from now on this reader reads nothing
        try:
            for i in range(600):  # 12 MB of events, far more than the socket buffers hold
                bus.publish("pose", {"x": i, "padding": padding})
                time.sleep(0.001)
            unsent = [channel.total_outbufs_len for channel in list(server._map.values())
                      if hasattr(channel, "total_outbufs_len")]
            assert max(unsent) <= STREAM_BACKLOG + 2 * len(padding), unsent
        finally:
            sock.close()


def test_streams_end_when_the_event_bus_closes(robot_config, store, bus):
    with _serve(robot_config, store, bus) as (_, url), EventReader(url, kinds=ROBOT_STATE) as reader:
        bus.publish("mode", {"mode": "idle"})
        reader.next()
        bus.close()  # the server is stopping
        assert reader.next() is None and reader.ended
        late = EventReader(url, kinds=ROBOT_STATE)  # one opened meanwhile ends at once too
        assert late.next() is None and late.ended


def test_a_stream_is_dropped_by_the_kernel_when_its_peer_stops_acknowledging(robot_config, store, bus):
    """A phone that walks out of Wi-Fi range never answers: its stream's connection times out in
    ``channel_timeout`` (TCP_USER_TIMEOUT) instead of TCP's ~15 minutes, freeing its place."""
    robot_config.server.channel_timeout = 12.0
    bus.publish("mode", {"mode": "idle"})
    with _serve(robot_config, store, bus) as (server, url), EventReader(url, kinds=ROBOT_STATE) as reader:
        reader.next()
        streams = [channel for channel in list(server._map.values()) if getattr(channel, "requests", None)]
        assert len(streams) == 1
        timeout = streams[0].socket.getsockopt(socket.IPPROTO_TCP, socket.TCP_USER_TIMEOUT)
        assert timeout == 12000


def test_a_page_knows_it_is_connected_at_once_even_when_nothing_has_happened_yet(robot_config, store, bus):
    """The answer's headers come with a first chunk written at once, not with the first event (or
    the first heartbeat, 15 s later: past the reader's 10 s timeout)."""
    with _serve(robot_config, store, bus) as (_, url), EventReader(url, kinds=("estop",)) as reader:
        assert reader.status_code == 200
        bus.publish("estop", {"latched": True, "source": "api", "since": None})
        assert reader.next() == ("estop", {"latched": True, "source": "api", "since": None})
        assert reader.retry == 2000


def test_one_address_gets_at_most_half_the_stream_places():
    """A machine on the Wi-Fi opening streams it never reads cannot take every place from the owner's phone."""
    gate = StreamGate(max_streams=8)
    taken = [gate.enter("192.168.1.66") for _ in range(4)]
    with pytest.raises(TooManyStreams) as refused:
        gate.enter("192.168.1.66")
    assert "192.168.1.66" in str(refused.value) and "half of server.max_streams" in str(refused.value)
    phone = gate.enter("192.168.1.20")  # the owner's phone still gets in
    gate.leave(taken.pop())
    gate.leave(gate.enter("192.168.1.66"))  # a place given back is the address's again
    assert [gate.enter("127.0.0.1") for _ in range(4)] == [None] * 4  # this machine: not counted per address
    with pytest.raises(TooManyStreams):
        gate.enter("::1")  # ...but the total still holds
    gate.leave(phone)
