"""The robot's identity on the broker is its own, and someone else using it is noticed (issue 34, items 3 and 6).

Before: two robots left at the default name shared one client id and one set of topics (they knocked
each other off every second and one Home Assistant command drove both), any client could publish a
retained ``offline`` or a fake ``state`` on the robot's topics and Home Assistant believed it, and a
robot whose HTTP needed a token joined its broker anonymously with one INFO line. A real mosquitto,
real paho clients, the real MqttLink and, last, a real ``--sim`` server.
"""

import json
import re
import time

import pytest

from flask_move_server.config import MqttConfig
from flask_move_server.mqtt import identity
from flask_move_server.mqtt.identity import broker_name
from flask_move_server.mqtt.link import MqttLink
from flask_move_server.mqtt.trust import access_check
from tests.conftest import stop_process, wait_for
from tests.mqtt_broker import Broker, Listener, retained_on
from tests.test_home_assistant import MqttSim


@pytest.fixture(scope="module")
def broker(tmp_path_factory):
    b = Broker(tmp_path_factory.mktemp("identity_broker"))
    yield b
    b.stop()


@pytest.fixture
def stranger(broker):
    listener = Listener(broker, topics=())
    yield listener
    listener.close()


def link_on(broker, name):
    link = MqttLink(MqttConfig(enabled=True, host="127.0.0.1", port=broker.port, keepalive=5), name).start()
    wait_for(lambda: link.connected, message="the link connected")
    return link


# the name ------------------------------------------------------------------------------------------


def machine(tmp_path, text):
    path = tmp_path / "machine-id-{}".format(abs(hash(text)))
    path.write_text(text + "\n")
    return (str(path),)


def test_a_robot_left_at_the_default_name_gets_one_of_its_own_the_same_at_every_start(tmp_path):
    first = broker_name(None, "robot", machine(tmp_path, "3d1219c7c4c5404aaa1f6d2a48adfda4"))
    assert re.fullmatch(r"robot-[0-9a-f]{6}", first)
    assert broker_name(None, "robot", machine(tmp_path, "3d1219c7c4c5404aaa1f6d2a48adfda4")) == first
    assert broker_name(None, "robot", machine(tmp_path, "0f1e2d3c4b5a69788796a5b4c3d2e1f0")) != first
    assert "3d1219c7" not in first  # the machine id itself is not told to the broker


def test_a_name_the_owner_gave_is_used_as_it_is(tmp_path):
    ids = machine(tmp_path, "3d1219c7c4c5404aaa1f6d2a48adfda4")
    assert broker_name(None, "kitchen-bot", ids) == "kitchen-bot"
    assert broker_name("Robbie", "robot", ids) == "Robbie"
    assert broker_name("robot", "robot", ids) == "robot"  # an owner keeping the old topics says so


def test_without_a_machine_id_the_default_stays_and_the_log_says_how_to_choose(tmp_path, caplog):
    assert broker_name(None, "robot", (str(tmp_path / "none"),)) == "robot"
    assert "set mqtt.name" in caplog.text


# someone else speaking as the robot --------------------------------------------------------------


def test_a_fake_state_or_a_retained_offline_from_another_client_is_noticed_and_outlived(broker, stranger,
                                                                                        monkeypatch):
    monkeypatch.setattr(identity, "WILL_WINDOW", 0.0)  # the stranger's "offline" comes right after the connect
    link = link_on(broker, "robot-fake")
    root = "flask-move-server/robot-fake"
    try:
        ours = json.dumps({"status": "idle", "target": None})
        for _ in range(5):  # our own messages, echoed back, are ours
            link.publish(root + "/state", ours, retain=True)
        wait_for(lambda: retained_on(broker, root + "/state", wait=0.3) == ours, message="our state retained")
        assert link.status()["identity"]["state"] == "own" and link.status()["identity"]["foreign_messages"] == 0
        stranger.send(root + "/availability", "offline", retain=True)  # Home Assistant would show it unavailable
        stranger.send(root + "/state", json.dumps({"status": "driving", "target": "front door"}), retain=True)
        wait_for(lambda: link.status()["identity"]["foreign_messages"] == 2, message="the other client noticed")
        told = link.status()["identity"]
        assert told["state"] == "shared" and "someone faking it" in told["message"] and told["since"]
        wait_for(lambda: retained_on(broker, root + "/availability", wait=0.3) == "online", timeout=10,
                 message="online re-asserted")
        wait_for(lambda: retained_on(broker, root + "/state", wait=0.3) == ours, timeout=10,
                 message="our state re-asserted")
    finally:
        link.close()


def test_what_the_broker_kept_of_the_robot_s_last_life_is_not_someone_else(broker):
    first = link_on(broker, "robot-again")
    first.publish("flask-move-server/robot-again/state", json.dumps({"status": "idle"}), retain=True)
    time.sleep(0.5)
    first.close()  # "offline" and the old state stay retained, as after a restart
    second = link_on(broker, "robot-again")
    try:
        wait_for(lambda: retained_on(broker, "flask-move-server/robot-again/availability", wait=0.3) == "online",
                 message="online again")
        time.sleep(1.0)
        assert second.status()["identity"]["state"] == "own"
        assert second.status()["identity"]["foreign_messages"] == 0
    finally:
        second.close()


def test_the_will_of_the_robot_s_own_connection_just_after_it_reconnected_is_its_own():
    now = [100.0]
    published = []
    watch = identity.IdentityWatch("robot-x", ("flask-move-server/robot-x/availability",
                                               "flask-move-server/robot-x/state"),
                                   reassert=lambda topic, payload: published.append((topic, payload)),
                                   clock=lambda: now[0])
    watch.connected()
    watch.sent("flask-move-server/robot-x/availability", "online", retain=True)
    now[0] += 0.5  # the broker ends the old connection it took over, and publishes its will
    watch.heard("flask-move-server/robot-x/availability", b"offline", retained=False)
    assert watch.status()["state"] == "own" and watch.status()["foreign_messages"] == 0
    assert published == [("flask-move-server/robot-x/availability", "online")]
    now[0] += identity.WILL_WINDOW  # later, an "offline" is someone else's
    watch.heard("flask-move-server/robot-x/availability", b"offline", retained=False)
    assert watch.status()["state"] == "shared" and watch.status()["foreign_messages"] == 1


def test_two_robots_of_one_name_see_each_other_and_say_it_once(broker, caplog):
    a, b = link_on(broker, "twin"), None
    try:
        # One client id for both: the broker ends one connection whenever the other connects.
        b = MqttLink(MqttConfig(enabled=True, host="127.0.0.1", port=broker.port, keepalive=5), "twin").start()
        wait_for(lambda: a.status()["identity"]["state"] == "taken" and b.status()["identity"]["state"] == "taken",
                 timeout=30, message="both twins telling their client id is taken")
        assert "another client uses its client id flask-move-server-twin" in a.status()["identity"]["message"]
        time.sleep(3)  # the knocking goes on: the log does not say it twice a second
        told = [r.getMessage() for r in caplog.records if "flask_move_server.mqtt" in r.name]
        assert sum("another client connects with this robot's client id" in m for m in told) == 2  # once each
        assert sum("lost the broker" in m for m in told) <= 2 * identity.KNOCKS
    finally:
        a.close()
        if b is not None:
            b.close()


# who can drive the robot through the broker -----------------------------------------------------------------


@pytest.mark.parametrize("host, username, tls, guarded, level, words", [
    ("broker.lan", None, False, True, "warn", "joined anonymously and in plain text"),
    ("broker.lan", "robot", False, True, "warn", "joined in plain text"),
    ("127.0.0.1", None, False, True, "warn", "joined anonymously:"),
    ("localhost", "robot", False, True, "pass", "joined as 'robot' on this machine"),
    ("broker.lan", "robot", True, True, "pass", "joined as 'robot' over TLS"),
    ("broker.lan", None, False, False, "pass", "HTTP needs no token either"),
])
def test_the_doctor_warns_when_the_token_does_not_guard_the_broker(host, username, tls, guarded, level, words):
    check = access_check(MqttConfig(enabled=True, host=host, username=username, tls=tls), guarded)
    assert check.level == level and words in check.summary
    if level == "warn":
        assert "docs/home-assistant.md" in check.advice or "TLS" in check.advice


def test_a_new_robot_is_named_its_own_and_told_what_guards_it_in_the_log_status_and_doctor(tmp_path, broker,
                                                                                           stranger):
    sim = MqttSim(tmp_path, broker, name=None, token="s3cret-token")
    try:
        name = broker_name(None, "robot")
        wait_for(lambda: sim.status()["mqtt"]["state"] == "connected", message="connected")
        mqtt = sim.status()["mqtt"]
        assert mqtt["topic_root"] == "flask-move-server/" + name and name != "robot"
        assert mqtt["identity"] == {"name": name, "state": "own", "foreign_messages": 0}
        assert sim.find(r"WARNING.*HTTP needs the token, but the broker 127\.0\.0\.1:\d+ is joined anonymously")
        assert sim.find(r"this robot is '{}' on the broker".format(name))
        checks = {c["name"]: c for c in sim.get("/diagnostics?seconds=1", timeout=30).json()["checks"]}
        assert checks["mqtt_access"]["level"] == "warn" and checks["mqtt_identity"]["level"] == "pass"
        stranger.send("flask-move-server/{}/state".format(name), json.dumps({"status": "idle"}), retain=True)
        wait_for(lambda: sim.status()["mqtt"]["identity"]["state"] == "shared", message="the stranger noticed")
        checks = {c["name"]: c for c in sim.get("/diagnostics?seconds=1", timeout=30).json()["checks"]}
        assert checks["mqtt_identity"]["level"] == "warn"
        assert sim.find(r"WARNING.*another client published on flask-move-server/{}/state".format(name))
    finally:
        stop_process(sim.proc)
