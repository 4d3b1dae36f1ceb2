"""A fleet manager's side of the VDA 5050 tests: a paho client on the vehicle's topics, and the robot.

``Fleet`` listens to everything under the vehicle's topics, sends orders and instant actions with
their headers as a master does, and checks every message the robot sent against the standard's
schemas (tests/vda_schemas.py). ``VdaSim`` is ``flask-move-server --sim`` with MQTT and VDA 5050 on.
"""

import itertools
import json

from tests.mqtt_broker import Listener
from tests.test_home_assistant import MqttSim
from tests.vda_schemas import check, problems

BASE = "uagv/v2/flask-move-server/robot/"
OUT = ("state", "visualization", "connection", "factsheet")  # what the robot sends
VDA_ON = "  vda5050:\n    enabled: true\n"


class VdaSim(MqttSim):
    def __init__(self, tmp_path, broker, extra=""):
        super().__init__(tmp_path, broker, extra=VDA_ON + extra)


class Fleet(Listener):
    """The master's view: the vehicle's messages, kept; orders and instant actions sent."""

    def __init__(self, broker, base=BASE):
        super().__init__(broker, topics=(base + "#",))
        self.base = base
        self._ids = itertools.count(1)
        self._checked = 0

    def header(self):
        return {"headerId": next(self._ids), "timestamp": "2026-11-27T17:00:00.00Z", "version": "2.0.0",
                "manufacturer": self.base.split("/")[2], "serialNumber": self.base.split("/")[3]}  # the topic's

    def send_order(self, order_id, nodes, edges, update=0):
        message = dict(self.header(), orderId=order_id, orderUpdateId=update, nodes=nodes, edges=edges)
        check("order", message)  # what the tests send is a real order (unless sent raw)
        self.send(self.base + "order", json.dumps(message))
        return message

    def instant(self, *actions):
        """Send instant actions: each ``(actionId, actionType)`` or ``(actionId, actionType, parameters)``."""
        message = dict(self.header(), actions=[
            {"actionId": a[0], "actionType": a[1], "blockingType": "HARD",
             "actionParameters": [{"key": k, "value": v} for k, v in (a[2] if len(a) > 2 else {}).items()]}
            for a in actions])
        check("instantActions", message)
        self.send(self.base + "instantActions", json.dumps(message))

    def raw(self, topic, payload):
        self.send(self.base + topic, payload)

    def states(self):
        return [json.loads(text) for _t, text, _r in self.on(self.base + "state")]

    def state(self, predicate=lambda s: True, timeout=20, message=None):
        """The newest state once ``predicate`` holds for it."""
        return self.wait_json(self.base + "state", predicate, timeout=timeout, message=message)

    def ask_state(self, predicate=lambda s: True, timeout=20, message=None):
        """A state sent after this call (stateRequest) once ``predicate`` holds for one."""
        seen = len(self.on(self.base + "state"))
        self.instant(("ask-{}".format(next(self._ids)), "stateRequest"))
        from tests.conftest import wait_for

        def newer():
            fresh = [json.loads(t) for _t, t, _r in self.on(self.base + "state")[seen:]]
            return next((s for s in reversed(fresh) if predicate(s)), None)
        return wait_for(newer, timeout=timeout, message=message or "a state answering the stateRequest")

    def unchecked_problems(self):
        """Schema problems of the robot's messages not checked yet, as sentences; they count as checked then."""
        with self._lock:
            fresh, self._checked = self.messages[self._checked:], len(self.messages)
        found = []
        for _t, topic, text, _r in fresh:
            kind = topic[len(self.base):]
            if kind in OUT and text:
                found += ["{} #{}: {}".format(kind, json.loads(text).get("headerId"), p)
                          for p in problems(kind, json.loads(text))]
        return found


def where(state):
    """``nodePosition`` of the robot's place in ``state`` (a first node trivially reachable)."""
    p = state["agvPosition"]
    return {"x": p["x"], "y": p["y"], "mapId": p["mapId"]}


def node(node_id, seq, released=True, position=None, **more):
    data = {"nodeId": node_id, "sequenceId": seq, "released": released, "actions": []}
    if position is not None:
        data["nodePosition"] = dict(position, **more)
    return data


def edges_of(nodes):
    """The edges joining ``nodes``, released where both ends are."""
    return [{"edgeId": "{}-{}".format(a["nodeId"], b["nodeId"]), "sequenceId": a["sequenceId"] + 1,
             "released": a["released"] and b["released"], "startNodeId": a["nodeId"], "endNodeId": b["nodeId"],
             "actions": []} for a, b in zip(nodes, nodes[1:])]


def error_types(state):
    return [e["errorType"] for e in state["errors"]]
