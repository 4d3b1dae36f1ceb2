"""Home Assistant's MQTT discovery: the robot appears in Home Assistant by itself, as one device.

Retained configs under ``<prefix>/<component>/<robot>/<object>/config`` (docs/home-assistant.md):
selects Go to (the active map's waypoints) and Route, buttons Stop, Dock, Pause, Resume, E-stop,
sensors Status (an enum; its attributes: the sentence, the last refused command, the run), Target,
Mode and Dock (enums), Map, Last reached, Battery (once the robot has heard one; its config is never
removed at a start before a reading comes, so the entity an owner renamed stays), the binary sensor
E-stop latched, the events Arrival and Run ended (``ha_events.py``), and a switch
per zone of the active map ("Katzenecke: keep out"; a deleted zone's switch is removed). Every
entity reads ``<root>/state`` and is available while ``<root>/availability`` says ``online``.

Published at each connect and again when Home Assistant says ``online`` on ``<prefix>/status``
(its birth message, after a restart); the selects again when the waypoints, the routes, the map or
the mode change. With ``home_assistant.enabled: false`` each config is removed (an empty retained
message), so the device leaves Home Assistant. :func:`discovery` is pure; :class:`HomeAssistant`
publishes it from one thread, woken by those events. No paho here (the link publishes).
"""

import json
import logging
import threading

from flask_move_server import __version__
from flask_move_server.dock.docking import STATES as DOCK_STATES
from flask_move_server.modes.targets import MODES
from flask_move_server.mqtt.ha_events import ARRIVAL_TYPES, RUN_TYPES, arrival_topic, run_topic
from flask_move_server.zones import zone_object_id

log = logging.getLogger(__name__)

MANUFACTURER = "flask-move-server"
MODEL = "ROS 1 robot"
NONE = "None"  # what Home Assistant's MQTT select and sensor read as "no value"
WAKING_KINDS = ("waypoints", "map", "mode", "zone")
SWITCH = "/switch/"  # the zones' switches: one per zone, removed with it

STATUSES = ("idle", "moving", "arrived", "failed", "stopped", "teleop", "paused", "exploring", "stuck", "estop",
            "docking", "docked", "charging")  # robot_state._status's words, and stuck
BUTTONS = (("stop", "Stop", "mdi:stop"), ("dock", "Dock", "mdi:home-import-outline"),
           ("pause", "Pause", "mdi:pause"), ("resume", "Resume", "mdi:play"),
           ("estop", "E-stop", "mdi:alert-octagon"))
SENSORS = (("target", "Target", "mdi:map-marker-path", "value_json.target", None),
           ("mode", "Mode", "mdi:robot", "value_json.mode", MODES),
           ("map", "Map", "mdi:map", "value_json.map", None),
           ("last_reached", "Last reached", "mdi:map-marker-check", "value_json.last_reached", None),
           ("dock", "Dock", "mdi:ev-station", "value_json.dock", DOCK_STATES))


def discovery(prefix, root, robot, device, waypoints, routes, battery_known, enabled=True, vda_connection=None,
              zones=()):
    """Every ``(config topic, payload)`` of the robot's entities; payload "" removes one.

    ``zones``: the active map's Zones, a switch each ("Katzenecke: keep out", on while it keeps the robot out).
    ``vda_connection``: the VDA 5050 ``connection`` topic, which holds the connection's one last will
    when the robot is a VDA 5050 vehicle too: Home Assistant then follows it beside ``availability``.
    """
    common = {"availability_topic": root + "/availability", "device": device,
              "origin": {"name": MANUFACTURER, "sw_version": __version__}}
    if vda_connection is not None:
        del common["availability_topic"]
        common["availability"] = [{"topic": root + "/availability"}, {
            "topic": vda_connection, "payload_available": "online", "payload_not_available": "offline",
            "value_template": "{{ 'online' if value_json.connectionState == 'ONLINE' else 'offline' }}"}]
        common["availability_mode"] = "all"  # a crash leaves availability "online": the will says otherwise
    state = root + "/state"
    configs = [
        ("select", "goto", {"name": "Go to", "icon": "mdi:map-marker", "command_topic": root + "/goto/set",
                            "options": list(waypoints), "state_topic": state,
                            "value_template": _one_of("value_json.target", waypoints)}),
        ("select", "route", {"name": "Route", "icon": "mdi:map-marker-multiple", "command_topic": root + "/route/set",
                             "options": list(routes), "state_topic": state,
                             "value_template": _or_none("value_json.run.route if value_json.run else none")}),
        ("sensor", "status", {"name": "Status", "icon": "mdi:robot-outline", "state_topic": state,
                              "device_class": "enum", "options": list(STATUSES),
                              "value_template": "{{ value_json.status }}", "json_attributes_topic": state,
                              "json_attributes_template": "{{ {'message': value_json.message, 'refused': "
                                                          "value_json.refused, 'run': value_json.run} | tojson }}"}),
        ("binary_sensor", "estop", {"name": "E-stop latched", "device_class": "safety", "state_topic": state,
                                    "value_template": "{{ 'ON' if value_json.estop else 'OFF' }}"}),
    ]
    configs += [("button", obj, {"name": name, "icon": icon, "command_topic": "{}/{}/press".format(root, obj),
                                 "payload_press": "PRESS"}) for obj, name, icon in BUTTONS]
    configs += [("sensor", obj, _sensor(name, icon, state, value, options))
                for obj, name, icon, value, options in SENSORS]
    if battery_known or not enabled:  # not heard yet: its config of an earlier start is left, never removed
        configs.append(("sensor", "battery", {
            "name": "Battery", "device_class": "battery", "unit_of_measurement": "%", "state_class": "measurement",
            "state_topic": state, "value_template": _or_none("value_json.battery.percentage if value_json.battery "
                                                             "else none")}))
    configs += [("event", "arrival", {"name": "Arrival", "icon": "mdi:map-marker-check",
                                      "event_types": list(ARRIVAL_TYPES), "state_topic": arrival_topic(root)}),
                ("event", "run_ended", {"name": "Run ended", "icon": "mdi:flag-checkered",
                                        "event_types": list(RUN_TYPES), "state_topic": run_topic(root)})]
    configs += [("switch", zone_object_id(zone.name), _zone_switch(root, state, zone)) for zone in zones]
    out = []
    for component, obj, config in configs:
        topic = "{}/{}/{}/{}/config".format(prefix, component, robot, obj)
        keep = enabled
        unique_id = "{}_{}_{}_{}".format(MANUFACTURER, robot, component, obj)
        payload = json.dumps(dict(common, unique_id=unique_id, **config), ensure_ascii=False, sort_keys=True)
        out.append((topic, payload if keep else ""))
    return out


def _sensor(name, icon, state, value, options):
    """A sensor of the state topic; with ``options``, an enum (Home Assistant offers its states in automations)."""
    config = {"name": name, "icon": icon, "state_topic": state, "value_template": _or_none(value)}
    if options:
        config.update(device_class="enum", options=list(options))
    return config


def _zone_switch(root, state, zone):
    object_id = zone_object_id(zone.name)
    return {"name": "{}: keep out".format(zone.name), "icon": "mdi:wall" if zone.kind == "wall" else "mdi:cancel",
            "command_topic": "{}/zone/{}/set".format(root, object_id), "payload_on": "ON", "payload_off": "OFF",
            "state_topic": state, "value_template": "{{{{ 'ON' if (value_json.zones or {{}}).get('{}') else 'OFF' }}}}"
            .format(object_id)}


def _one_of(expression, options):
    """A template that gives ``expression`` when it is one of ``options``, else None: a select shown a
    value it does not offer (a place deleted while the robot drives there) logs an error each time."""
    return "{{% set v = {} %}}{{{{ v if v in {} else '{}' }}}}".format(
        expression, json.dumps(list(options), ensure_ascii=False), NONE)


def _or_none(expression):
    """A template that gives ``expression``, or None (Home Assistant's "no value") when it is empty."""
    return "{{% set v = {} %}}{{{{ v if v not in (none, '') else '{}' }}}}".format(expression, NONE)


def device_info(robot, name, configuration_url):
    """The one device all entities belong to."""
    return {"identifiers": ["{}_{}".format(MANUFACTURER, robot)], "name": name, "manufacturer": MANUFACTURER,
            "model": MODEL, "sw_version": __version__, "configuration_url": configuration_url}


class HomeAssistant:
    """Publishes the discovery configs on ``link`` when they are due (see the module's docstring)."""

    def __init__(self, link, config, robot_name, device, store, events=None, vda_connection=None):
        self._link, self._config, self._robot_name, self._device = link, config, robot_name, device
        self._vda_connection = vda_connection
        self._store = store
        self._battery_known = False  # told by the state topic (battery_heard), never read off the robot here
        self.status_topic = config.discovery_prefix + "/status"
        self._told = {}  # config topic -> payload last published
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread = None
        link.when_connected(self.republish)
        link.handle(self.status_topic, self._home_assistant_said, takes_retained=True)
        if events is not None:
            for kind in WAKING_KINDS:
                events.listen(kind, lambda data: self._wake.set())

    def start(self):
        self._thread = threading.Thread(target=self._run, name="mqtt-discovery", daemon=True)
        self._thread.start()
        return self

    def republish(self):
        """Publish every config again (a connect, Home Assistant's birth)."""
        self._told = {}
        self._wake.set()

    def battery_heard(self):
        """The state has a battery now: its sensor is due."""
        self._battery_known = True
        self._wake.set()

    def _home_assistant_said(self, payload):
        if payload == "online":
            log.info("MQTT: Home Assistant came online: publishing the discovery again")
            self.republish()

    def _run(self):
        while not self._stop.is_set():
            self._wake.wait()
            self._wake.clear()
            if self._stop.is_set():
                return
            try:
                self.publish_due()
            except Exception:
                log.exception("MQTT: publishing Home Assistant's discovery failed")

    def publish_due(self):
        """Publish the configs that differ from the last published; the number published."""
        if not self._link.connected:
            return 0
        told = 0
        configs = self.configs()
        gone = {topic for topic in self._told if SWITCH in topic} - {topic for topic, _ in configs}
        for topic, payload in configs + [(topic, "") for topic in sorted(gone)]:  # a deleted zone's switch goes
            if self._told.get(topic) != payload and self._link.publish(topic, payload, retain=True):
                self._told[topic] = payload
                told += 1
        for topic in gone:
            self._told.pop(topic, None)
        return told

    def configs(self):
        waypoints = [wp.name for wp in self._store.all()]
        routes = [route.name for route in self._store.routes()]
        return discovery(self._config.discovery_prefix, self._link.root, self._robot_name, self._device,
                         waypoints, routes, self._battery_known, enabled=self._config.enabled,
                         vda_connection=self._vda_connection, zones=self._store.zones())

    def close(self):
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
