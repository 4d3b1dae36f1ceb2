"""Home Assistant over MQTT, against a real broker (Debian's mosquitto) and ``flask-move-server --sim``.

What an owner sees in Home Assistant: the device and its entities appear by themselves (the
discovery payloads, field by field), "Go to" sends the robot, Stop stops it, a new place appears
among the options, a refused command says why on the Status sensor, and Home Assistant's restart
(its birth message) brings everything back. The paho in use is whichever the venv has: PyPI's 2.x
under ``make test``, Debian's 1.6 under ``make test-debian``.
"""

import json
import time

import pytest
import requests

from tests.conftest import stop_process, wait_for
from tests.mqtt_broker import Broker, Listener, retained_on
from tests.test_sim_e2e import SimServer

WAYPOINTS = ["kitchen", "office", "bedroom", "sofa", "dock"]  # config/waypoints.demo.yaml, in file order
ROOT_TOPIC = "flask-move-server/robot"
STATE = ROOT_TOPIC + "/state"
PREFIX = "homeassistant"
ENTITIES = {  # (component, object) -> name, as Home Assistant shows them
    ("select", "goto"): "Go to", ("select", "route"): "Route",
    ("button", "stop"): "Stop", ("button", "dock"): "Dock", ("button", "pause"): "Pause",
    ("button", "resume"): "Resume", ("button", "estop"): "E-stop",
    ("sensor", "status"): "Status", ("sensor", "target"): "Target", ("sensor", "mode"): "Mode",
    ("sensor", "map"): "Map", ("sensor", "last_reached"): "Last reached",
    ("binary_sensor", "estop"): "E-stop latched",  # not "E-stop" twice: the button is that
    ("event", "arrival"): "Arrival", ("event", "run_ended"): "Run ended",
}


class MqttSim(SimServer):
    """``flask-move-server --sim`` with MQTT on, talking to ``broker``; ``name``: ``mqtt.name`` (None: left
    out, so the robot names itself); ``top``: more top-level config; ``token``: HTTP's, sent by get and post."""

    def __init__(self, tmp_path, broker, extra="", name="robot", top="", token=None):
        tmp_path.mkdir(parents=True, exist_ok=True)
        if token:
            self.headers = {"Authorization": "Bearer " + token}
            top += "server:\n  token: {}\n".format(token)
        named = "  name: {}\n".format(name) if name else ""
        super().__init__(tmp_path, sim_config="{}mqtt:\n  enabled: true\n  host: 127.0.0.1\n  port: {}\n"
                                              "  keepalive: 5\n{}{}".format(top, broker.port, named, extra))
        self.port = int(self.url.rsplit(":", 1)[1])

    def navigation(self):
        return self.status()["navigation"]


@pytest.fixture(scope="module")
def broker(tmp_path_factory):
    b = Broker(tmp_path_factory.mktemp("broker"))
    yield b
    b.stop()


@pytest.fixture(scope="module")
def home(broker):
    """Home Assistant's side: everything the broker carries."""
    listener = Listener(broker)
    yield listener
    listener.close()


@pytest.fixture(scope="module")
def sim(tmp_path_factory, broker, home):
    server = MqttSim(tmp_path_factory.mktemp("ha_sim"), broker)
    yield server
    stop_process(server.proc)


def config_of(home, component, obj):
    return home.wait_json("{}/{}/robot/{}/config".format(PREFIX, component, obj),
                          message="the discovery config of {} {}".format(component, obj))


def test_the_robot_appears_as_one_device_with_every_entity(sim, home, broker):
    assert home.wait_last(ROOT_TOPIC + "/availability") == "online"
    device = {"identifiers": ["flask-move-server_robot"], "name": "robot", "manufacturer": "flask-move-server",
              "model": "ROS 1 robot", "configuration_url": "http://robot.local:{}/".format(sim.port)}
    unique_ids = set()
    for (component, obj), name in ENTITIES.items():
        config = config_of(home, component, obj)
        assert config["name"] == name
        assert config["availability_topic"] == ROOT_TOPIC + "/availability"
        assert {k: config["device"][k] for k in device} == device
        assert config["device"]["sw_version"]
        unique_ids.add(config["unique_id"])
        if component in ("select", "button"):
            kind = "set" if component == "select" else "press"
            assert config["command_topic"] == "{}/{}/{}".format(ROOT_TOPIC, obj, kind)
        if component in ("select", "sensor", "binary_sensor"):
            assert config["state_topic"] == STATE
    assert len(unique_ids) == len(ENTITIES)  # each entity its own unique_id
    # Retained: Home Assistant started after the robot (a fresh subscriber) still finds them all.
    assert json.loads(retained_on(broker, "{}/select/robot/goto/config".format(PREFIX)))["options"] == WAYPOINTS
    assert retained_on(broker, ROOT_TOPIC + "/availability") == "online"
    assert json.loads(retained_on(broker, STATE))["mode"] == "navigation"
    assert config_of(home, "select", "goto")["options"] == WAYPOINTS
    assert config_of(home, "button", "stop")["payload_press"] == "PRESS"
    assert config_of(home, "binary_sensor", "estop")["device_class"] == "safety"
    # The sim's battery is heard within a second, so its sensor comes too (a robot without a fuel gauge
    # has none, rather than one showing "unknown" for ever: test_mqtt_parts).
    battery = config_of(home, "sensor", "battery")
    assert battery["device_class"] == "battery" and battery["unit_of_measurement"] == "%"


def test_the_state_says_what_the_robot_does(sim, home):
    state = home.wait_json(STATE)
    assert set(state) == {"status", "message", "mode", "map", "target", "last_reached", "run", "estop", "pose",
                          "battery", "dock", "refused", "zones"}
    assert state["mode"] == "navigation" and state["estop"] is False
    assert set(state["pose"]) == {"x", "y", "yaw"}
    battery = home.wait_json(STATE, lambda s: s["battery"] is not None)["battery"]
    assert set(battery) == {"percentage", "voltage", "charging", "age"} and 0 <= battery["percentage"] <= 100


def test_go_to_sends_the_robot_and_stop_stops_it(sim, home):
    home.send(ROOT_TOPIC + "/goto/set", "kitchen")
    wait_for(lambda: sim.navigation()["target"] == "kitchen" and sim.navigation()["state"] == "active",
             message="the robot on its way to the kitchen")
    moving = home.wait_json(STATE, lambda s: s["status"] == "moving" and s["target"] == "kitchen")
    assert moving["refused"] is None
    home.send(ROOT_TOPIC + "/stop/press", "PRESS")
    wait_for(lambda: sim.navigation()["state"] == "canceled", message="the goal canceled by Stop")
    home.wait_json(STATE, lambda s: s["status"] == "stopped" and s["target"] is None)
    motors = sim.get("/status").json()["motors"]
    wait_for(lambda: sim.get("/status").json()["motors"]["left"] == 0, message="the motors at rest") or motors


def test_dock_docks_onto_the_charger_and_the_house_hears_it_charging(sim, home):
    home.send(ROOT_TOPIC + "/dock/press", "PRESS")
    state = home.wait_json(STATE, lambda s: s["status"] == "docking", message="on its way home")
    assert state["dock"] in ("going", "approaching") and state["message"] == "Going home to dock."
    state = home.wait_json(STATE, lambda s: s["status"] == "charging", timeout=60, message="charging on the dock")
    assert state["dock"] == "charging" and state["message"] == "Charging at dock."
    config = config_of(home, "sensor", "dock")
    assert config["state_topic"] == STATE and config["name"] == "Dock"


def test_a_refused_command_says_why_and_moves_nothing(sim, home):
    before = sim.navigation()
    home.send(ROOT_TOPIC + "/goto/set", "garage")
    refused = home.wait_json(STATE, lambda s: s["refused"] is not None)["refused"]
    assert refused["command"] == "goto" and "garage" in refused["message"]
    assert sim.navigation()["goal_id"] == before["goal_id"]  # no goal sent
    home.send(ROOT_TOPIC + "/pause/press", "PRESS")
    refused = home.wait_json(STATE, lambda s: (s["refused"] or {}).get("command") == "pause")["refused"]
    assert "No run" in refused["message"]


def test_dock_goes_to_the_charger_by_the_owners_name_and_without_one_says_so(sim, home):
    charger = "Ladestelle Küche"
    dock = sim.get("/waypoints/dock").json()
    put = dict(dock, dock=True)
    del put["name"]
    assert requests.put(sim.url + "/waypoints/" + charger, json=put, timeout=10).status_code == 201
    try:
        sim.post("/undock")  # on the charger since the test before: off it, to dock again
        wait_for(lambda: sim.get("/status").json()["dock"]["state"] == "undocked", timeout=30, message="undocked")
        home.send(ROOT_TOPIC + "/dock/press", "PRESS")
        home.wait_json(STATE, lambda s: s["status"] in ("docking", "charging") and charger in (s["message"] or ""),
                       timeout=30, message="docking at the charger, by its name")
        sim.post("/stop")
        assert requests.delete(sim.url + "/waypoints/dock", timeout=10).status_code == 204
        assert requests.delete(sim.url + "/waypoints/" + charger, timeout=10).status_code == 204
        before = sim.navigation()
        home.send(ROOT_TOPIC + "/dock/press", "PRESS")
        refused = home.wait_json(STATE, lambda s: (s["refused"] or {}).get("command") == "dock")["refused"]
        assert refused["message"].startswith("This map has no dock."), refused
        assert sim.navigation()["goal_id"] == before["goal_id"]  # no goal sent
    finally:
        body = {k: dock[k] for k in ("x", "y", "yaw")}
        assert requests.put(sim.url + "/waypoints/dock", json=body, timeout=10).status_code in (200, 201)


def test_the_e_stop_from_home_assistant_latches_and_refuses_goals(sim, home):
    home.send(ROOT_TOPIC + "/estop/press", "PRESS")
    home.wait_json(STATE, lambda s: s["estop"] is True and s["status"] == "estop")
    assert sim.get("/status").json()["estop"]["source"] == "mqtt"
    home.send(ROOT_TOPIC + "/goto/set", "sofa")
    refused = home.wait_json(STATE, lambda s: (s["refused"] or {}).get("command") == "goto")["refused"]
    assert "e-stop" in refused["message"].lower()
    assert sim.navigation()["state"] != "active"
    assert sim.post("/estop/release").status_code == 200
    home.wait_json(STATE, lambda s: s["estop"] is False)


def test_a_new_place_and_a_new_route_appear_among_the_options(sim, home):
    assert sim.get("/status").status_code == 200
    r = requests.put(sim.url + "/waypoints/porch", json={"x": 1.0, "y": 0.5, "yaw": 0.0}, timeout=10)
    assert r.status_code == 201
    goto = home.wait_json("{}/select/robot/goto/config".format(PREFIX), lambda c: "porch" in c["options"],
                          message="porch among the Go to options")
    assert goto["options"] == WAYPOINTS + ["porch"]
    r = requests.put(sim.url + "/routes/rounds", json={"waypoints": ["porch", "dock"]}, timeout=10)
    assert r.status_code == 201, r.text
    home.wait_json("{}/select/robot/route/config".format(PREFIX), lambda c: c["options"] == ["rounds"],
                   message="the route among the Route options")


def test_a_route_from_home_assistant_is_a_run(sim, home):
    home.send(ROOT_TOPIC + "/route/set", "rounds")
    state = home.wait_json(STATE, lambda s: s["run"] is not None and s["run"]["route"] == "rounds")
    assert state["run"]["state"] == "running"
    run = sim.get("/runs").json()["runs"][0]
    assert run["route"] == "rounds" and run["trigger"] == "mqtt"
    home.send(ROOT_TOPIC + "/pause/press", "PRESS")
    home.wait_json(STATE, lambda s: s["status"] == "paused")
    home.send(ROOT_TOPIC + "/stop/press", "PRESS")
    wait_for(lambda: sim.get("/runs").json()["runs"][0]["state"] == "canceled", message="the run ended by Stop")
    ended = home.wait_json(ROOT_TOPIC + "/event/run", message="the Run ended event")
    assert (ended["event_type"], ended["id"], ended["route"]) == ("canceled", run["id"], "rounds"), ended
    assert config_of(home, "event", "run_ended")["event_types"] == ["succeeded", "failed", "canceled", "skipped"]


def test_a_goal_from_home_assistant_ends_a_run_and_the_run_says_who_sent_it(sim, home):
    home.send(ROOT_TOPIC + "/route/set", "rounds")
    run = home.wait_json(STATE, lambda s: (s["run"] or {}).get("state") == "running")["run"]
    home.send(ROOT_TOPIC + "/goto/set", "sofa")
    wait_for(lambda: sim.get("/runs/{}".format(run["id"])).json()["state"] == "canceled", message="the run ended")
    ended = sim.get("/runs/{}".format(run["id"])).json()
    assert ended["message"] == "A goal to sofa (MQTT goto/set) took the robot elsewhere."
    wait_for(lambda: sim.navigation()["target"] == "sofa", message="the goal that ended it under way")
    home.send(ROOT_TOPIC + "/stop/press", "PRESS")


def test_a_trip_of_about_a_second_is_told_moving_then_arrived(sim, home):
    # docs/home-assistant.md's "Robot arrived" automation triggers on Status turning arrived: a short
    # trip must show moving, then arrived (built once a second, the state could miss it)
    wait_for(lambda: sim.navigation()["state"] not in ("active", "canceling"), message="the last test's Stop")
    assert sim.put("/waypoints/Sofaecke", {"x": 0.0, "y": 1.0, "yaw": 3.14}).status_code in (200, 201)
    r = sim.post("/goto", {"name": "sofa", "wait": 90}, timeout=100)
    assert r.status_code == 200, r.text
    home.wait_json(STATE, lambda s: s["status"] == "arrived" and s["last_reached"] == "sofa")
    home.clear()
    home.send(ROOT_TOPIC + "/goto/set", "Sofaecke")  # half a metre: about a second at the sim's speed
    wait_for(lambda: [s["status"] for s in _states(home)][-1:] == ["arrived"] and "moving" in
             [s["status"] for s in _states(home)], timeout=15, message="moving, then arrived, on the state topic")
    said = [s["status"] for s in _states(home)]
    assert said.index("moving") < len(said) - 1 and said[-1] == "arrived", said
    # there already: a trip too short for the state to show, yet a second Arrival event at that place
    home.send(ROOT_TOPIC + "/goto/set", "Sofaecke")
    arrivals = lambda: [json.loads(t) for _t, t, _r in home.on(ROOT_TOPIC + "/event/arrival")]  # noqa: E731
    wait_for(lambda: len(arrivals()) >= 2, timeout=15, message="two Arrival events")
    assert [(a["event_type"], a["place"]) for a in arrivals()] == [("arrived", "Sofaecke")] * 2
    assert all(not retained for _t, _text, retained in home.on(ROOT_TOPIC + "/event/arrival"))
    assert sim.delete("/waypoints/Sofaecke").status_code == 204


def _states(home):
    return [json.loads(text) for _t, text, _r in home.on(STATE) if text]


def test_the_status_mode_and_dock_sensors_are_enums_of_every_word_they_say(sim, broker):
    def retained(obj):
        return json.loads(retained_on(broker, "{}/sensor/robot/{}/config".format(PREFIX, obj)))
    status, dock = retained("status"), retained("dock")
    assert status["device_class"] == "enum" == dock["device_class"]
    assert {"moving", "arrived", "failed", "stuck", "estop"} <= set(status["options"])
    assert retained("mode")["options"] == ["idle", "mapping", "navigation"] and "charging" in dock["options"]
    state = json.loads(retained_on(broker, STATE))
    assert state["status"] in status["options"] and state["dock"] in dock["options"]


def test_a_restart_before_the_battery_is_heard_keeps_its_sensor_an_owner_may_have_renamed(broker, home, tmp_path):
    topic = PREFIX + "/sensor/rover/battery/config"
    first = MqttSim(tmp_path / "one", broker, name="rover")
    try:
        config = home.wait_json(topic, message="the battery's sensor once the sim's battery is heard")
    finally:
        stop_process(first.proc)
    home.clear()
    again = MqttSim(tmp_path / "two", broker, name="rover")  # discovery comes at connect, the battery after
    try:
        home.wait_json(PREFIX + "/sensor/rover/status/config", message="the discovery of the second start")
        time.sleep(2.0)
        assert all(text for _t, text, _r in home.on(topic)), "the battery's config was emptied at the start"
        kept = json.loads(retained_on(broker, topic))
        assert kept["unique_id"] == config["unique_id"] and kept["device_class"] == "battery"
    finally:
        stop_process(again.proc)


def test_home_assistant_s_restart_brings_the_discovery_back(sim, home):
    home.clear()
    home.send(PREFIX + "/status", "online")
    for component, obj in ENTITIES:
        config_of(home, component, obj)  # each published again


def test_a_goto_to_the_robot_s_own_topic_is_taken_only_from_its_command_topic(sim, home):
    """The state topic is the robot's: a client writing on it does not command anything."""
    goal = sim.navigation()["goal_id"]
    home.send(STATE, json.dumps({"status": "moving", "target": "kitchen"}))
    home.send(ROOT_TOPIC + "/goto", "kitchen")
    home.send(ROOT_TOPIC + "/goto/set/extra", "kitchen")
    import time

    time.sleep(1.0)
    assert sim.navigation()["goal_id"] == goal


def test_a_zone_is_a_switch_that_keeps_the_robot_out_or_lets_it_in(sim, home, broker):
    from flask_move_server.zones import zone_object_id

    square = [[1.5, 0.0], [2.5, 0.0], [2.5, 1.3], [1.5, 1.3]]
    assert sim.put("/zones/Katzenecke", {"kind": "keepout", "polygon": square}).status_code == 201
    object_id = zone_object_id("Katzenecke")
    topic = "{}/switch/robot/{}/config".format(PREFIX, object_id)
    switch = home.wait_json(topic, message="the zone's switch")
    assert switch["name"] == "Katzenecke: keep out" and switch["state_topic"] == STATE
    assert switch["command_topic"] == "{}/zone/{}/set".format(ROOT_TOPIC, object_id)
    assert (switch["payload_on"], switch["payload_off"]) == ("ON", "OFF")
    home.wait_json(STATE, lambda s: s["zones"] == {object_id: True}, message="the zone on in the state")
    home.send(switch["command_topic"], "OFF")  # "today the robot may go there"
    wait_for(lambda: sim.get("/zones/Katzenecke").json()["enabled"] is False, message="the zone switched off")
    home.wait_json(STATE, lambda s: s["zones"] == {object_id: False}, message="the zone off in the state")
    home.send(switch["command_topic"], "maybe")
    refused = home.wait_json(STATE, lambda s: s["refused"] is not None, message="the refusal")["refused"]
    assert refused["command"] == "zone" and "ON or OFF" in refused["message"]
    assert sim.get("/zones/Katzenecke").json()["enabled"] is False  # nothing changed
    home.send(switch["command_topic"], "ON")
    wait_for(lambda: sim.get("/zones/Katzenecke").json()["enabled"] is True, message="the zone switched on")
    assert sim.delete("/zones/Katzenecke").status_code == 204
    wait_for(lambda: home.last(topic) == "", message="the deleted zone's switch removed (an empty config)")
    assert retained_on(broker, topic) in (None, "")
