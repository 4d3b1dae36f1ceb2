"""A fleet manager's order (VDA 5050 2.0.0, section 6.6), checked, and the one the robot keeps.

``check(message)`` reads an order message: the fields the standard requires, their types, and
its structure (one edge fewer than nodes; sequence ids 0, 1, 2, … running over nodes and edges;
each edge joining the nodes beside it; the base — released nodes and edges — before the horizon).
What is wrong raises :class:`Refusal` with the standard's error type: ``validationError``.

:class:`OrderBook` keeps the order being done, and decides on a new message as the standard's
Figure 8 does:

- another ``orderId``: refused (``orderUpdateError``) while the robot still has nodes or edges
  to do; else taken when its first node is trivially reachable (``noRouteError`` when not);
- the same ``orderId``: a lower ``orderUpdateId`` is refused (``orderUpdateError``), an equal
  one is ignored, a higher one is stitched on: its first node must be the last base node
  (still under way) or the last node traversed (the order done), else ``orderUpdateError``.

The robot drives only the base; the horizon is shown (``nodeStates``) but never driven. Pure:
no MQTT, no rospy.
"""

import copy
import math
from dataclasses import dataclass

from flask_move_server.core.geometry import Pose2D

HEADER = (("headerId", int), ("timestamp", str), ("version", str), ("manufacturer", str), ("serialNumber", str))
MAX_NODES = 200  # nodes in one order message (the factsheet says so)
MAX_ID = 200  # characters of an id (the factsheet's maxStringLens)
FIRST_NODE_DEVIATION = 0.5  # m: how far the robot may stand from a first node without an allowedDeviationXY
MAX_COORDINATE = 1e6  # m (or rad): a position or angle beyond this is no place on a map


class Refusal(Exception):
    """An order (or instant action) refused: ``error_type`` and ``references`` as the state's ``errors`` say."""

    def __init__(self, error_type, description, references=()):
        super().__init__(description)
        self.error_type = error_type
        self.references = list(references)

    def as_error(self, level="WARNING"):
        return {"errorType": self.error_type, "errorLevel": level, "errorDescription": str(self),
                "errorReferences": [{"referenceKey": k, "referenceValue": str(v)} for k, v in self.references]}


@dataclass(frozen=True)
class Stop:
    """A released node to drive to: its id and sequence id, and its pose (None: the node names a waypoint)."""

    node_id: str
    sequence_id: int
    pose: object


# reading a message -----------------------------------------------------------

def check(message):
    """The order in ``message`` (a parsed JSON value), its structure checked; Refusal (validationError)."""
    if not isinstance(message, dict):
        raise _invalid("An order is a JSON object.")
    for key, kind in HEADER + (("orderId", str), ("orderUpdateId", int), ("nodes", list), ("edges", list)):
        _field(message, key, kind, "order")
    if message["orderUpdateId"] < 0:
        raise _invalid("orderUpdateId must be 0 or more.", [("orderId", message["orderId"])])
    nodes, edges = message["nodes"], message["edges"]
    if not nodes or len(nodes) > MAX_NODES:
        raise _invalid("An order has 1 to {} nodes, not {}.".format(MAX_NODES, len(nodes)))
    for node in nodes:
        _node(node)
    for edge in edges:
        _edge(edge)
    _structure(nodes, edges)
    return message


def _field(data, key, kind, what, optional=False):
    if key not in data:
        if optional:
            return None
        raise _invalid("The {} has no '{}'.".format(what, key))
    value = data[key]
    if not _is(value, kind):
        raise _invalid("'{}' of the {} must be {}.".format(key, what, _KINDS[kind]))
    if kind is str and len(value) > MAX_ID:
        raise _invalid("'{}' of the {} is longer than {} characters.".format(key, what, MAX_ID))
    if kind is int and value < 0:
        raise _invalid("'{}' of the {} must be 0 or more.".format(key, what))
    return value


def finite(number):
    """A number a pose can hold: not NaN or infinite, and not an integer too large for a float."""
    try:
        return math.isfinite(number) and abs(number) <= MAX_COORDINATE
    except OverflowError:
        return False


def _is(value, kind):
    if kind is bool:
        return isinstance(value, bool)
    if isinstance(value, bool):
        return False
    if kind is float:
        return isinstance(value, (int, float)) and finite(value)
    return isinstance(value, kind)


_KINDS = {int: "a whole number", str: "text", list: "a list", bool: "true or false", float: "a number",
          dict: "an object"}


def _node(node):
    if not isinstance(node, dict):
        raise _invalid("Each node is an object.")
    for key, kind in (("nodeId", str), ("sequenceId", int), ("released", bool), ("actions", list)):
        _field(node, key, kind, "node")
    position = _field(node, "nodePosition", dict, "node {}".format(node["nodeId"]), optional=True)
    if position is not None:
        what = "nodePosition of node {}".format(node["nodeId"])
        for key in ("x", "y"):
            _field(position, key, float, what)
        _field(position, "mapId", str, what)
        for key in ("theta", "allowedDeviationXY", "allowedDeviationTheta"):
            _field(position, key, float, what, optional=True)
    _actions(node["actions"], "node", node["nodeId"])


def _edge(edge):
    if not isinstance(edge, dict):
        raise _invalid("Each edge is an object.")
    for key, kind in (("edgeId", str), ("sequenceId", int), ("released", bool), ("startNodeId", str),
                      ("endNodeId", str), ("actions", list)):
        _field(edge, key, kind, "edge")
    _actions(edge["actions"], "edge", edge["edgeId"])


def _actions(actions, owner, owner_id):
    for action in actions:
        if not isinstance(action, dict):
            raise _invalid("Each action of {} {} is an object.".format(owner, owner_id))
        for key in ("actionType", "actionId", "blockingType"):
            _field(action, key, str, "action of {} {}".format(owner, owner_id))


def _structure(nodes, edges):
    """Edges join consecutive nodes; sequence ids run 2k (node), 2k+1 (edge); base before horizon."""
    if len(edges) != len(nodes) - 1:
        raise _invalid("An order of {} nodes needs {} edges, not {}.".format(len(nodes), len(nodes) - 1, len(edges)))
    first = nodes[0]["sequenceId"]
    if first % 2:
        raise _invalid("A node's sequenceId is even; node {} has {}.".format(nodes[0]["nodeId"], first),
                       [("nodeId", nodes[0]["nodeId"])])
    for i, node in enumerate(nodes):
        if node["sequenceId"] != first + 2 * i:
            raise _invalid("Node {} has sequenceId {}, not {}: nodes and edges count on together.".format(
                node["nodeId"], node["sequenceId"], first + 2 * i), [("nodeId", node["nodeId"])])
    for i, edge in enumerate(edges):
        start, end = nodes[i], nodes[i + 1]
        if edge["sequenceId"] != start["sequenceId"] + 1:
            raise _invalid("Edge {} has sequenceId {}, not {}.".format(
                edge["edgeId"], edge["sequenceId"], start["sequenceId"] + 1), [("edgeId", edge["edgeId"])])
        if (edge["startNodeId"], edge["endNodeId"]) != (start["nodeId"], end["nodeId"]):
            raise _invalid("Edge {} joins {} to {}, but it lies between nodes {} and {}.".format(
                edge["edgeId"], edge["startNodeId"], edge["endNodeId"], start["nodeId"], end["nodeId"]),
                [("edgeId", edge["edgeId"])])
        if edge["released"] and not end["released"]:
            raise _invalid("Edge {} is released, but its end node {} is not.".format(edge["edgeId"], end["nodeId"]),
                           [("edgeId", edge["edgeId"])])
    _base_first(nodes, edges)
    if not nodes[0]["released"]:
        raise _invalid("The first node of an order is released (it is where the robot stands).",
                       [("nodeId", nodes[0]["nodeId"])])


def _base_first(nodes, edges):
    """Section 6.6.1: after an unreleased node or edge, nothing released follows (in their one sequence)."""
    sequence = [nodes[0]] + [part for pair in zip(edges, nodes[1:]) for part in pair]
    for earlier, later in zip(sequence, sequence[1:]):
        if later["released"] and not earlier["released"]:
            what, key = ("node", "nodeId") if "nodeId" in later else ("edge", "edgeId")
            raise _invalid("Released {} {} follows one that is not: the base comes before the horizon.".format(
                what, later[key]), [(key, later[key])])


def _invalid(description, references=()):
    return Refusal("validationError", description, references)


# what the robot can do -------------------------------------------------------

def unsupported(order):
    """Refusal (orderError) naming each node and edge action, and each edge trajectory: this robot drives
    between poses and does nothing else on the way (its factsheet lists no node or edge actions)."""
    refs = [("actionType", a["actionType"]) for part in order["nodes"] + order["edges"] for a in part["actions"]]
    if refs:
        names = sorted({v for _, v in refs})
        raise Refusal("orderError", "This robot does no actions on nodes or edges (only driving): {}.".format(
            ", ".join(names)), refs)
    curved = [("edgeId", e["edgeId"]) for e in order["edges"] if "trajectory" in e]
    if curved:
        raise Refusal("orderError", "This robot plans its own path: edges with a trajectory are not taken.", curved)


def stops_of(nodes, map_id, waypoints):
    """The nodes to drive to, as :class:`Stop` s: a ``nodePosition`` on ``map_id`` (Refusal orderError on
    another map), else the waypoint called ``nodeId`` (``waypoints``: name → Pose2D; Refusal orderError
    when there is none)."""
    stops, previous = [], None
    for node in nodes:
        position = node.get("nodePosition")
        if position is None:
            if node["nodeId"] not in waypoints:
                raise Refusal("orderError", "Node {} has no nodePosition, and no waypoint of map {} is called so."
                              .format(node["nodeId"], map_id), [("nodeId", node["nodeId"])])
            pose, previous = None, waypoints[node["nodeId"]]
        else:
            if position["mapId"] != map_id:
                raise Refusal("orderError", "Node {} is on map {}, but the robot navigates on {}.".format(
                    node["nodeId"], position["mapId"], map_id), [("nodeId", node["nodeId"]),
                                                                ("mapId", position["mapId"])])
            pose = Pose2D(float(position["x"]), float(position["y"]), _theta(position, previous))
            previous = pose
        stops.append(Stop(node["nodeId"], node["sequenceId"], pose))
    return stops


def _theta(position, previous):
    """The node's theta, or else the heading from the node before (the robot may turn freely there)."""
    if "theta" in position:
        return float(position["theta"])
    if previous is not None and (position["x"], position["y"]) != (previous.x, previous.y):
        return math.atan2(position["y"] - previous.y, position["x"] - previous.x)
    return previous.yaw if previous is not None else 0.0


def within_reach(node, here, waypoint_pose):
    """Is ``node`` (an order's first) trivially reachable from ``here`` (a Pose2D, or None: unknown)?"""
    if here is None:
        return False
    position = node.get("nodePosition")
    target = waypoint_pose if position is None else Pose2D(position["x"], position["y"], 0.0)
    if target is None:
        return False
    allowed = (position or {}).get("allowedDeviationXY") or FIRST_NODE_DEVIATION
    return math.hypot(target.x - here.x, target.y - here.y) <= allowed


# the order the robot keeps ---------------------------------------------------

NEW, UPDATE, IGNORE = "new", "update", "ignore"


class OrderBook:
    """The order being done: its ids, the nodes and edges left (base and horizon), the last node passed."""

    def __init__(self):
        self.order_id, self.update_id = "", 0
        self.last_node_id, self.last_node_seq = "", 0
        self.nodes, self.edges = [], []  # left to do, in order

    @property
    def busy(self):
        """Nodes or edges still to do (base or horizon): another order is refused until they are done."""
        return bool(self.nodes or self.edges)

    @property
    def horizon(self):
        """Whether nodes are announced but not released: the robot waits at the last base node for them."""
        return any(not n["released"] for n in self.nodes)

    def decide(self, order, reachable):
        """``NEW``, ``UPDATE`` or ``IGNORE`` for ``order`` (checked), as the standard's Figure 8;
        ``reachable(node)`` says whether a new order's first node is trivially reachable. Refusal otherwise."""
        ids = [("orderId", order["orderId"]), ("orderUpdateId", order["orderUpdateId"])]
        first = order["nodes"][0]
        if order["orderId"] != self.order_id:
            if self.busy:
                raise Refusal("orderUpdateError", "Order {} is still under way: cancel it (instant action "
                              "cancelOrder) before sending order {}.".format(self.order_id, order["orderId"]), ids)
            if not reachable(first):
                raise Refusal("noRouteError", "The first node {} is not where the robot stands (within its "
                              "allowedDeviationXY, else {} m).".format(first["nodeId"], FIRST_NODE_DEVIATION),
                              [("nodeId", first["nodeId"])])
            return NEW
        if order["orderUpdateId"] < self.update_id:
            raise Refusal("orderUpdateError", "orderUpdateId {} is lower than {}, the order's update in force."
                          .format(order["orderUpdateId"], self.update_id), ids)
        if order["orderUpdateId"] == self.update_id:
            return IGNORE
        stitch = self._last_base() if self.busy else (self.last_node_id, self.last_node_seq)
        if (first["nodeId"], first["sequenceId"]) != stitch:
            raise Refusal("orderUpdateError", "The update's first node is {} ({}), but it must be the last base "
                          "node {} ({}).".format(first["nodeId"], first["sequenceId"], *stitch), ids)
        return UPDATE

    def _last_base(self):
        """``(nodeId, sequenceId)`` of the last released node still to do, or the last passed."""
        released = [n for n in self.nodes if n["released"]]
        if released:
            return released[-1]["nodeId"], released[-1]["sequenceId"]
        return self.last_node_id, self.last_node_seq

    def take(self, order, kind):
        """Keep ``order`` as ``kind`` decided; the released nodes it adds to drive to (its first node, the
        robot's place or the stitching node, is never one). Refusal (orderError) when the nodes left to do
        would be more than MAX_NODES (an update piling base on base faster than the robot drives)."""
        nodes, edges = [dict(n) for n in order["nodes"]], [dict(e) for e in order["edges"]]
        if kind == UPDATE and self.busy:
            left = len([n for n in self.nodes if n["released"]]) + len(nodes) - 1
            if left > MAX_NODES:
                raise Refusal("orderError", "With this update the robot would have {} nodes to do, more than the "
                              "{} it keeps: send more once it has driven some.".format(left, MAX_NODES),
                              [("orderId", order["orderId"]), ("orderUpdateId", order["orderUpdateId"])])
        self.order_id, self.update_id = order["orderId"], order["orderUpdateId"]
        if kind == NEW or not self.busy:
            self.nodes, self.edges = nodes, edges
            self.passed(nodes[0]["sequenceId"], nodes[0]["nodeId"])
        else:  # stitched on: the horizon goes, the update's own base and horizon follow the last base node
            self.nodes = [n for n in self.nodes if n["released"]] + nodes[1:]
            self.edges = [e for e in self.edges if e["released"]] + edges
        return [n for n in nodes[1:] if n["released"]]

    def passed(self, sequence_id, node_id):
        """The robot reached node ``sequence_id``: it and the edge before it are done."""
        self.nodes = [n for n in self.nodes if n["sequenceId"] > sequence_id]
        self.edges = [e for e in self.edges if e["sequenceId"] > sequence_id]
        self.last_node_id, self.last_node_seq = node_id, sequence_id

    def drop(self):
        """The order ends unfinished (canceled, failed): nothing is left to do; the ids are kept."""
        self.nodes, self.edges = [], []

    def copy(self):
        return copy.deepcopy(self)

    def caught_up(self, newer):
        """This book (a copy kept before an update that could not start) with what ``newer`` saw the
        robot do since: the nodes passed, or the order dropped. Returns self."""
        if not newer.busy:
            self.drop()
        elif newer.order_id == self.order_id and newer.last_node_seq > self.last_node_seq:
            self.passed(newer.last_node_seq, newer.last_node_id)
        return self

    def node_states(self):
        return [_node_state(n) for n in self.nodes]

    def edge_states(self):
        return [{"edgeId": e["edgeId"], "sequenceId": e["sequenceId"], "released": e["released"]}
                for e in self.edges]


def _node_state(node):
    state = {"nodeId": node["nodeId"], "sequenceId": node["sequenceId"], "released": node["released"]}
    position = node.get("nodePosition")
    if position is not None:
        state["nodePosition"] = {k: position[k] for k in ("x", "y", "theta", "mapId") if k in position}
    return state
