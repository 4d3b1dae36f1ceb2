"""The pure parts of the MQTT bridge: the discovery payloads, their templates as Home Assistant renders
them (Jinja2, as Home Assistant does, with ``value_json``), the one-word status, ``--mqtt``."""

import json

import jinja2
import pytest

from flask_move_server.app.server_options import load_config, parse_args
from flask_move_server.core.errors import ConfigError
from flask_move_server.mqtt.home_assistant import device_info, discovery
from flask_move_server.mqtt.robot_state import _status

ROOT = "flask-move-server/robo"
DEVICE = device_info("robo", "Robo", "http://robo.local:5000/")


def configs(**kw):
    args = dict(prefix="homeassistant", root=ROOT, robot="robo", device=DEVICE, waypoints=["kitchen", "Küche"],
                routes=["rounds"], battery_known=True)
    args.update(kw)
    return {topic: (json.loads(payload) if payload else None) for topic, payload in discovery(**args)}


def render(template, state):
    """What Home Assistant shows for ``template`` given the state topic's ``state``."""
    env = jinja2.Environment()
    return env.from_string(template).render(value_json=state)


STATE = {"status": "moving", "message": None, "mode": "navigation", "map": "flat", "target": "Küche",
         "last_reached": None, "run": None, "estop": False, "pose": {"x": 1.0, "y": 2.0, "yaw": 0.5},
         "battery": {"percentage": 62.0, "voltage": 12.1, "charging": False, "age": 0.4}, "dock": "undocked",
         "refused": None}


def test_every_config_topic_is_under_the_prefix_with_the_robot_s_name():
    found = configs()
    assert len(found) == 17  # the Dock sensor beside the Dock button; the Arrival and Run ended events
    for topic in found:
        prefix, component, robot, _obj, config = topic.split("/")
        assert (prefix, robot, config) == ("homeassistant", "robo", "config")
        assert component in ("select", "button", "sensor", "binary_sensor", "event")


def test_names_of_places_in_any_language_stay_as_they_are():
    goto = configs()["homeassistant/select/robo/goto/config"]
    assert goto["options"] == ["kitchen", "Küche"]
    assert render(goto["value_template"], STATE) == "Küche"


def test_the_templates_give_what_home_assistant_should_show():
    found = configs()

    def shown(component, obj, state):
        return render(found["homeassistant/{}/robo/{}/config".format(component, obj)]["value_template"], state)

    assert shown("sensor", "status", STATE) == "moving"
    assert shown("sensor", "battery", STATE) == "62.0"
    assert shown("sensor", "map", STATE) == "flat"
    assert shown("binary_sensor", "estop", STATE) == "OFF"
    assert shown("binary_sensor", "estop", dict(STATE, estop=True)) == "ON"
    # Nothing to say is Home Assistant's "None" (unknown), never an empty or "null" string.
    idle = dict(STATE, target=None, last_reached=None, battery=None, map=None)
    for obj in ("target", "last_reached", "battery", "map"):
        assert shown("sensor", obj, idle) == "None"
    assert shown("select", "goto", idle) == "None"
    assert shown("select", "route", STATE) == "None"
    assert shown("select", "route", dict(STATE, run={"id": 3, "route": "rounds", "state": "running"})) == "rounds"
    attributes = found["homeassistant/sensor/robo/status/config"]["json_attributes_template"]
    refused = {"command": "goto", "message": "No waypoint named 'garage'.", "at": "2026-11-27T14:00:00+00:00"}
    assert json.loads(render(attributes, dict(STATE, refused=refused)))["refused"] == refused


def test_without_a_battery_reading_its_sensor_is_neither_made_nor_removed():
    # a robot without a fuel gauge gets none; one whose reading is yet to come keeps the config of its
    # last start (an empty one would delete the entity the owner renamed, and make it anew a second later)
    assert "homeassistant/sensor/robo/battery/config" not in configs(battery_known=False)
    assert configs(battery_known=False, enabled=False)["homeassistant/sensor/robo/battery/config"] is None


def test_the_status_mode_and_dock_sensors_offer_every_word_the_state_can_hold():
    from flask_move_server.dock.docking import STATES as DOCK_STATES
    from flask_move_server.modes.targets import MODES

    found = configs()
    status = found["homeassistant/sensor/robo/status/config"]
    said = {_status(nav, teleop, estop, run, exploring, dock)
            for nav in [{}] + [{"state": s} for s in ("active", "succeeded", "aborted", "canceled", "stuck", "lost")]
            for teleop in ({}, {"active": True}) for estop in (False, True)
            for run in (None, {"state": "paused"}, {"state": "stuck"}) for exploring in (False, True)
            for dock in (None, "going", "docked", "charging", "failed")} | {"stuck"}
    assert status["device_class"] == "enum" and said <= set(status["options"]), said - set(status["options"])
    assert found["homeassistant/sensor/robo/mode/config"]["options"] == list(MODES)
    assert set(found["homeassistant/sensor/robo/dock/config"]["options"]) == set(DOCK_STATES)
    assert render(found["homeassistant/sensor/robo/mode/config"]["value_template"], dict(STATE, mode=None)) == "None"


@pytest.mark.parametrize("names", [["kitchen", "Küche"], ['say "hi"', "{{ 7 }}", "a %} b", "厨房", "it's"]])
def test_go_to_shows_the_target_only_while_it_is_one_of_the_places(names):
    template = configs(waypoints=names)["homeassistant/select/robo/goto/config"]["value_template"]
    for name in names:
        assert render(template, dict(STATE, target=name)) == name
    assert render(template, dict(STATE, target="deleted meanwhile")) == "None"
    assert render(template, dict(STATE, target=None)) == "None"


def test_arrivals_and_runs_ends_are_event_entities_of_their_own_topics():
    found = configs()
    arrival = found["homeassistant/event/robo/arrival/config"]
    assert arrival["state_topic"] == ROOT + "/event/arrival" and arrival["event_types"] == ["arrived", "failed"]
    run = found["homeassistant/event/robo/run_ended/config"]
    assert run["state_topic"] == ROOT + "/event/run" and "canceled" in run["event_types"]


def test_discovery_off_removes_every_entity():
    assert set(configs(enabled=False).values()) == {None}


def test_the_device_links_to_the_phone_page():
    goto = configs()["homeassistant/select/robo/goto/config"]
    assert goto["device"]["configuration_url"] == "http://robo.local:5000/"
    assert goto["availability_topic"] == ROOT + "/availability"
    assert goto["unique_id"] == "flask-move-server_robo_select_goto"


@pytest.mark.parametrize("nav, teleop, estop, run, exploring, word", [
    ({"state": "active"}, {}, False, None, False, "moving"),
    ({"state": "succeeded"}, {}, False, None, False, "arrived"),
    ({"state": "aborted"}, {}, False, None, False, "failed"),
    ({"state": "canceled"}, {}, False, None, False, "stopped"),
    ({"state": "idle"}, {"active": True}, False, None, False, "teleop"),
    ({"state": "active"}, {}, True, None, False, "estop"),
    ({"state": "canceled"}, {}, False, {"state": "paused"}, False, "paused"),
    ({"state": "active"}, {}, False, None, True, "exploring"),
    ({"state": "idle"}, {}, False, None, False, "idle"),
])
def test_one_word_says_what_the_robot_does(nav, teleop, estop, run, exploring, word):
    assert _status(nav, teleop, estop, run, exploring) == word


def test_the_mqtt_flag_turns_mqtt_on_for_that_broker():
    config = load_config(parse_args(["--sim", "--mqtt", "hub.lan:1884"]), [])
    assert (config.mqtt.enabled, config.mqtt.host, config.mqtt.port) == (True, "hub.lan", 1884)
    config = load_config(parse_args(["--sim", "--mqtt", "hub.lan"]), [])
    assert (config.mqtt.host, config.mqtt.port) == ("hub.lan", 1883)
    with pytest.raises(ConfigError, match="--mqtt"):
        load_config(parse_args(["--sim", "--mqtt", "hub.lan:99999"]), [])


def test_the_dock_sensor_and_the_status_say_what_the_docking_does():
    from flask_move_server.mqtt.robot_state import _status

    dock = configs()["homeassistant/sensor/robo/dock/config"]
    assert dock["name"] == "Dock" and render(dock["value_template"], dict(STATE, dock="charging")) == "charging"
    assert _status({"state": "active"}, {}, False, None, False, "going") == "docking"
    assert _status({"state": "succeeded"}, {"active": True}, False, None, False, "approaching") == "docking"
    assert _status({"state": "succeeded"}, {}, False, None, False, "charging") == "charging"
    assert _status({"state": "succeeded"}, {}, False, None, False, "undocked") == "arrived"
    assert _status({"state": "active"}, {}, True, None, False, "going") == "estop"
