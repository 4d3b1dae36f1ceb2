"""The messages a VDA 5050 vehicle sends besides ``state``: their header, ``connection``, ``factsheet``.

Each topic counts its own ``headerId`` from 0 (section 6.4); timestamps are UTC, ISO 8601, to the
millisecond, ``Z``. The factsheet says what this robot really is: its speeds and acceleration from
the local planner's config, its footprint from the costmap's, the instant actions it takes (and no
node or edge actions: it only drives), and the protocol limits it checks. Pure: no MQTT, no rospy.
"""

import datetime
import itertools
import threading

from flask_move_server.vda5050.order import MAX_ID, MAX_NODES

INSTANT_ACTIONS = {
    "cancelOrder": "Stops the robot where it is and drops the order.",
    "startPause": "Stops the robot where it is; the order waits (stopPause goes on).",
    "stopPause": "Drives on with the order.",
    "initPosition": "Tells localization where the robot is (x, y, theta on mapId, the active map).",
    "stateRequest": "Sends the state now.",
    "factsheetRequest": "Sends the factsheet now.",
    "startCharging": "Goes home onto the active map's charger and charges (RUNNING until it charges).",
    "stopCharging": "Backs straight off the charger.",
}
INIT_POSITION = (("x", "FLOAT"), ("y", "FLOAT"), ("theta", "FLOAT"), ("mapId", "STRING"), ("lastNodeId", "STRING"))
MAX_PAYLOAD = 256 * 1024  # bytes of an order or instant actions message taken (the factsheet's msgLen)
MAX_ACTIONS = 50  # instant actions in one message
# Bytes of a state message: its node and edge states are at most an order's (MAX_PAYLOAD), its action
# states and errors at most report.py's KEPT_*_BYTES; past it (a bug), action states then errors are left out.
MAX_STATE = 2 * MAX_PAYLOAD


def timestamp(now=None):
    """UTC now as the standard writes it: ``2026-11-27T17:04:57.123Z``."""
    now = now or datetime.datetime.now(datetime.timezone.utc)
    return now.strftime("%Y-%m-%dT%H:%M:%S.") + "{:03d}Z".format(now.microsecond // 1000)


class Headers:
    """The header of each message, with a ``headerId`` counted per topic."""

    def __init__(self, version, manufacturer, serial_number):
        self._common = {"version": version, "manufacturer": manufacturer, "serialNumber": serial_number}
        self._counters = {}
        self._lock = threading.Lock()

    def identity(self):
        """(manufacturer, serialNumber): whom a message's header must name to be for this vehicle."""
        return self._common["manufacturer"], self._common["serialNumber"]

    def stamp(self, topic, body):
        """``body`` with the header of the next message on ``topic`` before it."""
        with self._lock:
            counter = self._counters.setdefault(topic, itertools.count())
            header_id = next(counter)
        return dict({"headerId": header_id, "timestamp": timestamp()}, **self._common, **body)


def connection(state):
    """The ``connection`` body: ``ONLINE``, ``OFFLINE`` or ``CONNECTIONBROKEN`` (the last will)."""
    return {"connectionState": state}


def factsheet(robot_name, limits, footprint):
    """The ``factsheet`` body: ``limits`` the local planner's (sim/dwa.py PlannerLimits), ``footprint`` the
    costmap's polygon (a list of [x, y]) or None."""
    xs = [p[0] for p in footprint or []] or [-0.15, 0.15]
    ys = [p[1] for p in footprint or []] or [-0.15, 0.15]
    return {
        "typeSpecification": {
            "seriesName": "flask-move-server ROS 1 robot",
            "seriesDescription": "{}: a ROS 1 move_base robot driven by flask-move-server".format(robot_name),
            "agvKinematic": "DIFF", "agvClass": "CARRIER", "maxLoadMass": 0,
            "localizationTypes": ["NATURAL"], "navigationTypes": ["AUTONOMOUS"]},
        "physicalParameters": {
            "speedMin": 0.0, "speedMax": float(limits.max_vel_trans),
            "accelerationMax": float(limits.acc_lim_x), "decelerationMax": float(limits.acc_lim_x),
            "heightMax": 0.3, "width": round(max(ys) - min(ys), 3), "length": round(max(xs) - min(xs), 3)},
        "protocolLimits": {
            "maxStringLens": {"msgLen": MAX_PAYLOAD, "idLen": MAX_ID},
            "maxArrayLens": {"order.nodes": MAX_NODES, "order.edges": MAX_NODES - 1,
                             "node.actions": 0, "edge.actions": 0, "instantActions": MAX_ACTIONS},
            "timing": {"minOrderInterval": 0.1, "minStateInterval": 0.1, "defaultStateInterval": 30.0,
                       "visualizationInterval": 1.0}},
        "protocolFeatures": {
            "optionalParameters": [
                {"parameter": "order.nodes.nodePosition", "support": "SUPPORTED",
                 "description": "Without it, the nodeId names a waypoint of the active map."}],  # no trajectory
            "agvActions": [_action(name, text) for name, text in INSTANT_ACTIONS.items()]},
        "agvGeometry": {"envelopes2d": [{"set": "footprint", "polygonPoints": [
            {"x": float(x), "y": float(y)} for x, y in footprint]}]} if footprint else {},
        "loadSpecification": {"loadPositions": [], "loadSets": []},
    }


def _action(name, description):
    action = {"actionType": name, "actionDescription": description, "actionScopes": ["INSTANT"]}
    if name == "initPosition":
        action["actionParameters"] = [{"key": key, "valueDataType": kind, "isOptional": key == "lastNodeId"}
                                      for key, kind in INIT_POSITION]
    return action

