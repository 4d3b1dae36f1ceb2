"""A broker that is down, restarted, flooded with commands, or never a broker at all changes nothing
else the robot does; a command left retained on the broker never moves it; the broker tells the
house when the robot vanishes (its last will) or leaves (a clean ``offline``).

Real mosquitto, real ``flask-move-server --sim`` processes, a paho client as Home Assistant.
"""

import json
import signal
import socket
import threading
import time

import pytest

from tests.conftest import stop_process, wait_for
from tests.mqtt_broker import Broker, Listener, retained_on
from tests.test_home_assistant import PREFIX, ROOT_TOPIC, STATE, MqttSim

AVAILABILITY = ROOT_TOPIC + "/availability"
GOTO = ROOT_TOPIC + "/goto/set"
STOP_BOUND = 2.0  # s: a /stop slower than this during the broker's trouble would be a regression (the bench measures)


@pytest.fixture
def broker(tmp_path):
    b = Broker(tmp_path)
    yield b
    b.stop()


def timed_stops(sim, seconds):
    """``/stop`` over HTTP again and again for ``seconds``: the slowest answer, and every answer's code."""
    slowest, codes = 0.0, set()
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        started = time.monotonic()
        codes.add(sim.post("/stop").status_code)
        slowest = max(slowest, time.monotonic() - started)
        time.sleep(0.05)
    return slowest, codes


def test_a_command_left_retained_on_the_broker_never_moves_the_robot(tmp_path, broker):
    setter = Listener(broker)
    setter.send(GOTO, "kitchen", retain=True)  # left there by a misconfigured automation
    setter.close()
    sim = MqttSim(tmp_path, broker)
    try:
        home = Listener(broker)
        home.wait_last(AVAILABILITY, lambda t: t == "online")
        wait_for(lambda: sim.find("ignored a retained message on " + GOTO), message="the warning in the log")
        time.sleep(1.0)
        assert sim.navigation()["target"] != "kitchen"
        assert sim.get("/status").json()["mqtt"]["retained"] >= 1
        home.send(GOTO, "kitchen")  # the same command, sent now, is taken
        wait_for(lambda: sim.navigation()["target"] == "kitchen", message="the live command taken")
        home.close()
    finally:
        stop_process(sim.proc)


def test_sigterm_says_offline_and_kill_9_leaves_it_to_the_last_will(tmp_path, broker):
    sim = MqttSim(tmp_path / "a", broker)
    home = Listener(broker)
    home.wait_last(AVAILABILITY, lambda t: t == "online")
    assert sim.stop(signal.SIGTERM) == 0
    home.wait_last(AVAILABILITY, lambda t: t == "offline", message="the clean offline")
    assert retained_on(broker, AVAILABILITY) == "offline"

    sim = MqttSim(tmp_path / "b", broker)
    home.wait_last(AVAILABILITY, lambda t: t == "online")
    sim.proc.kill()  # no goodbye: the broker's last will speaks for the robot
    sim.proc.wait()
    home.wait_last(AVAILABILITY, lambda t: t == "offline", timeout=15, message="the last will")
    assert retained_on(broker, AVAILABILITY) == "offline"
    home.close()


def test_a_broker_down_and_back_changes_nothing_else_then_everything_is_published_again(tmp_path, broker):
    sim = MqttSim(tmp_path, broker)
    try:
        Listener(broker).wait_last(AVAILABILITY, lambda t: t == "online")
        broker.kill()
        wait_for(lambda: sim.get("/status").json()["mqtt"]["state"] == "disconnected", message="the loss noticed")
        assert sim.get("/health").status_code == 200
        slowest, codes = timed_stops(sim, 3.0)
        assert codes == {200} and slowest < STOP_BOUND
        assert sim.post("/goto", {"name": "sofa"}).status_code == 202  # the robot goes on serving
        broker.start()  # the same port; it remembers nothing (no persistence)
        home = Listener(broker)
        home.wait_last(AVAILABILITY, lambda t: t == "online", timeout=40, message="the robot back on the broker")
        config = home.wait_json("{}/select/robot/goto/config".format(PREFIX))
        assert "sofa" in config["options"]
        home.wait_json(STATE, lambda s: s["target"] == "sofa" or s["status"] in ("arrived", "moving"))
        home.close()
    finally:
        stop_process(sim.proc)


def test_a_flood_of_commands_never_delays_stop(tmp_path, broker):
    sim = MqttSim(tmp_path, broker)
    try:
        home = Listener(broker)
        home.wait_last(AVAILABILITY, lambda t: t == "online")
        flood = threading.Thread(target=_flood, args=(broker, 1000, 1.0))
        flood.start()
        slowest, codes = timed_stops(sim, 1.5)
        flood.join()
        assert codes == {200} and slowest < STOP_BOUND
        assert sim.get("/status").json()["mqtt"]["dropped_in"] > 0  # cut short, not queued
        _until_no_new_goal(sim)  # what was taken is done; a Stop now ends it
        assert sim.post("/stop").status_code == 200
        # Never "aborted": a goal the /stop loop canceled before move_base heard it is canceled, not
        # lost (tests/test_phantom_goals.py; 2 runs in 5 said "aborted" with no reason before that).
        wait_for(lambda: sim.navigation()["state"] in ("canceled", "succeeded", "idle"),
                 message="the robot stopped")
        home.close()
    finally:
        stop_process(sim.proc)


def _until_no_new_goal(sim, quiet=1.0, timeout=30.0):
    """Wait until no goal has come for ``quiet`` s: the flood's last taken commands are goals by now.

    A fixed second was not always enough on a loaded machine: a command the broker delivered late
    became a goal after the test's Stop, and the robot was (rightly) driving again."""
    last, since = sim.navigation()["goal_id"], time.monotonic()
    deadline = since + timeout
    while time.monotonic() - since < quiet:
        assert time.monotonic() < deadline, "goals from the flood still came after {:.0f} s".format(timeout)
        time.sleep(0.1)
        now = sim.navigation()["goal_id"]
        if now != last:
            last, since = now, time.monotonic()


def _flood(broker, count, seconds):
    sender = Listener(broker, topics=())
    names = ["kitchen", "office", "sofa", "bedroom"]
    for i in range(count):
        sender.client.publish(GOTO, names[i % len(names)], qos=0)
        time.sleep(seconds / count)
    sender.close()


def test_payloads_no_command_is_made_of_are_ignored(tmp_path, broker):
    sim = MqttSim(tmp_path, broker)
    try:
        home = Listener(broker)
        home.wait_last(AVAILABILITY, lambda t: t == "online")
        goal = sim.navigation()["goal_id"]
        home.send(GOTO, "k" * (1024 * 1024))  # 1 MB
        home.send(GOTO, b"\xff\xfe\x00kitchen")
        home.send(GOTO, "")
        wait_for(lambda: sim.get("/status").json()["mqtt"].get("too_big") == 1, message="the 1 MB payload counted")
        state = home.wait_json(STATE, lambda s: s["refused"] is not None)
        assert len(json.dumps(state)) < 2000  # a refusal quotes a name, never the payload whole
        assert sim.navigation()["goal_id"] == goal
        home.close()
    finally:
        stop_process(sim.proc)


def test_a_server_that_is_no_broker_changes_nothing(tmp_path):
    """Something on the port that answers garbage (or nothing): the robot serves as ever, and says so."""
    liar = socket.socket()
    liar.bind(("127.0.0.1", 0))
    liar.listen(8)
    stop = threading.Event()
    threading.Thread(target=_lie, args=(liar, stop), daemon=True).start()

    class Fake:
        port = liar.getsockname()[1]

    sim = MqttSim(tmp_path, Fake)
    try:
        wait_for(lambda: sim.get("/status").json()["mqtt"]["state"] in ("disconnected", "refused"),
                 timeout=15, message="the lying broker noticed")
        slowest, codes = timed_stops(sim, 2.0)
        assert codes == {200} and slowest < STOP_BOUND
        assert sim.post("/goto", {"name": "sofa"}).status_code == 202
    finally:
        stop.set()
        stop_process(sim.proc)
        liar.close()


def _lie(server, stop):
    """Answer each connection with bytes no MQTT broker sends (a huge remaining length, then junk)."""
    server.settimeout(0.2)
    while not stop.is_set():
        try:
            conn, _ = server.accept()
        except OSError:
            continue
        try:
            conn.sendall(b"\x20\xff\xff\xff\x7f" + b"\x00" * 64)
            time.sleep(0.2)
        except OSError:
            pass
        finally:
            conn.close()


def test_discovery_turned_off_removes_the_device_from_home_assistant(tmp_path, broker):
    sim = MqttSim(tmp_path / "on", broker)
    goto = "{}/select/robot/goto/config".format(PREFIX)
    wait_for(lambda: retained_on(broker, goto, wait=0.3), message="the discovery published")
    assert sim.stop() == 0
    sim = MqttSim(tmp_path / "off", broker, extra="  home_assistant:\n    enabled: false\n")
    try:
        wait_for(lambda: retained_on(broker, goto, wait=0.3) is None, message="the Go to config removed")
        for component, obj in (("button", "stop"), ("sensor", "status"), ("binary_sensor", "estop")):
            assert retained_on(broker, "{}/{}/robot/{}/config".format(PREFIX, component, obj), wait=0.3) is None
        assert json.loads(retained_on(broker, STATE))["mode"] == "navigation"  # the state topic stays
    finally:
        stop_process(sim.proc)
