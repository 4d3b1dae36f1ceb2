"""A fleet manager's order, read and kept as VDA 5050 2.0.0 says (section 6.6 and its Figure 8).

The rules a master relies on: a malformed order is a ``validationError``; an order for another
map or with actions the robot cannot do is an ``orderError`` naming them; a first node away from
the robot is a ``noRouteError``; an update is stitched on the last base node, a lower one is an
``orderUpdateError``, an equal one is ignored; only released nodes are driven.
"""

import copy
import math

import pytest

from flask_move_server.core.geometry import Pose2D
from flask_move_server.vda5050 import messages
from flask_move_server.vda5050.order import (
    IGNORE,
    NEW,
    UPDATE,
    OrderBook,
    Refusal,
    check,
    stops_of,
    unsupported,
    within_reach,
)

HEADER = {"headerId": 1, "timestamp": "2026-11-27T17:00:00.00Z", "version": "2.0.0",
          "manufacturer": "flask-move-server", "serialNumber": "robot"}


def node(node_id, seq, released=True, x=None, y=0.0, map_id="demo", **position):
    data = {"nodeId": node_id, "sequenceId": seq, "released": released, "actions": []}
    if x is not None:
        data["nodePosition"] = dict({"x": x, "y": y, "mapId": map_id}, **position)
    return data


def edge(start, end, seq, released=True):
    return {"edgeId": "{}-{}".format(start, end), "sequenceId": seq, "released": released,
            "startNodeId": start, "endNodeId": end, "actions": []}


def order(nodes, order_id="o1", update=0, edges=None):
    """An order of ``nodes``; its edges join them, released where both ends are."""
    if edges is None:
        edges = [edge(a["nodeId"], b["nodeId"], a["sequenceId"] + 1, a["released"] and b["released"])
                 for a, b in zip(nodes, nodes[1:])]
    return dict(HEADER, orderId=order_id, orderUpdateId=update, nodes=nodes, edges=edges)


THREE = order([node("a", 0, x=0.0), node("b", 2, x=1.0), node("c", 4, x=2.0)])


def refusal(call, *args):
    with pytest.raises(Refusal) as caught:
        call(*args)
    return caught.value


# reading -------------------------------------------------------------------------

def test_a_well_formed_order_is_taken_as_sent():
    assert check(copy.deepcopy(THREE)) == THREE


@pytest.mark.parametrize("broken, words", [
    (lambda o: o.pop("orderId"), "no 'orderId'"),
    (lambda o: o.update(orderUpdateId="1"), "'orderUpdateId' of the order must be a whole number"),
    (lambda o: o.update(orderUpdateId=True), "'orderUpdateId' of the order must be a whole number"),
    (lambda o: o.update(nodes=[]), "1 to 200 nodes"),
    (lambda o: o["nodes"][1].update(released="yes"), "'released' of the node must be true or false"),
    (lambda o: o["nodes"][1]["nodePosition"].update(x=float("nan")), "'x' of the nodePosition of node b"),
    (lambda o: o["nodes"][1]["nodePosition"].pop("mapId"), "has no 'mapId'"),
    (lambda o: o["edges"].pop(), "needs 2 edges, not 1"),
    (lambda o: o["edges"][1].update(startNodeId="a"), "joins a to c, but it lies between nodes b and c"),
    (lambda o: o["nodes"][2].update(sequenceId=6), "sequenceId 6, not 4"),
    (lambda o: o["edges"][0].update(sequenceId=3), "sequenceId 3, not 1"),
    (lambda o: o["nodes"][1].update(released=False), "is released, but its end node b is not"),
    (lambda o: (o["nodes"][1].update(released=False), o["edges"][0].update(released=False)),
     "Released edge b-c follows one that is not"),
    (lambda o: o["edges"][0].update(released=False), "Released node b follows one that is not"),
    (lambda o: o["nodes"][1]["nodePosition"].update(x=10 ** 400), "'x' of the nodePosition of node b"),
    (lambda o: o["nodes"][1]["nodePosition"].update(y=2e6), "'y' of the nodePosition of node b"),
    (lambda o: o["nodes"][0].update(nodeId="x" * 201), "longer than 200 characters"),
])
def test_a_malformed_order_is_a_validation_error_saying_what_is_wrong(broken, words):
    bad = copy.deepcopy(THREE)
    broken(bad)
    found = refusal(check, bad)
    assert found.error_type == "validationError"
    assert words in str(found), str(found)


def test_an_order_is_a_json_object():
    assert refusal(check, ["not", "an", "order"]).error_type == "validationError"


def test_actions_on_nodes_and_edges_are_an_order_error_naming_each():
    asked = copy.deepcopy(THREE)
    asked["nodes"][1]["actions"] = [{"actionType": "pick", "actionId": "p1", "blockingType": "HARD"}]
    asked["edges"][0]["actions"] = [{"actionType": "beep", "actionId": "b1", "blockingType": "NONE"}]
    found = refusal(unsupported, check(asked))
    assert found.error_type == "orderError"
    assert "beep, pick" in str(found)
    assert found.as_error()["errorReferences"] == [{"referenceKey": "actionType", "referenceValue": "pick"},
                                                   {"referenceKey": "actionType", "referenceValue": "beep"}]


def test_an_edge_with_a_trajectory_is_an_order_error():
    curved = copy.deepcopy(THREE)
    curved["edges"][1]["trajectory"] = {"degree": 1, "knotVector": [], "controlPoints": []}
    assert refusal(unsupported, curved).error_type == "orderError"


# where the nodes are ----------------------------------------------------------

def test_a_node_is_its_position_or_the_waypoint_its_id_names():
    stops = stops_of([node("a", 0, x=0.0), node("kitchen", 2), node("c", 4, x=2.0, y=2.0)], "demo",
                     {"kitchen": Pose2D(2.0, 0.0, 0.0)})
    assert [(s.node_id, s.sequence_id) for s in stops] == [("a", 0), ("kitchen", 2), ("c", 4)]
    assert stops[1].pose is None
    assert stops[2].pose == Pose2D(2.0, 2.0, math.pi / 2)  # no theta: the way from the kitchen


def test_without_theta_a_node_faces_the_way_from_the_node_before():
    stops = stops_of([node("a", 0, x=0.0), node("b", 2, x=1.0, y=1.0), node("c", 4, x=1.0, y=2.0, theta=3.0)],
                     "demo", {})
    assert stops[1].pose.yaw == pytest.approx(math.pi / 4)
    assert stops[2].pose.yaw == 3.0


def test_a_node_on_another_map_or_naming_no_waypoint_is_an_order_error():
    other = refusal(stops_of, [node("a", 0, x=0.0, map_id="cellar")], "demo", {})
    assert other.error_type == "orderError" and "on map cellar" in str(other)
    unknown = refusal(stops_of, [node("pantry", 0)], "demo", {"kitchen": Pose2D(0.0, 0.0, 0.0)})
    assert unknown.error_type == "orderError" and "no waypoint of map demo is called so" in str(unknown)


def test_the_first_node_is_reachable_within_its_deviation_or_half_a_metre():
    here = Pose2D(0.0, 0.0, 0.0)
    assert within_reach(node("a", 0, x=0.4), here, None)
    assert not within_reach(node("a", 0, x=0.6), here, None)
    assert within_reach(node("a", 0, x=0.9, allowedDeviationXY=1.0), here, None)
    assert within_reach(node("dock", 0), here, Pose2D(0.1, 0.0, 0.0))
    assert not within_reach(node("a", 0, x=0.0), None, None)  # the pose is not known


# the order kept (Figure 8) -------------------------------------------------------

def taken(message, kind=NEW):
    book = OrderBook()
    book.take(check(message), kind)
    return book


def test_a_new_order_counts_its_first_node_passed_and_drives_the_released_rest():
    book = OrderBook()
    drive = book.take(check(copy.deepcopy(THREE)), NEW)
    assert [n["nodeId"] for n in drive] == ["b", "c"]
    assert (book.last_node_id, book.last_node_seq) == ("a", 0)
    assert [n["nodeId"] for n in book.nodes] == ["b", "c"] and book.busy


def test_only_the_base_is_driven_the_horizon_is_shown():
    book = OrderBook()
    drive = book.take(check(order([node("a", 0, x=0.0), node("b", 2, x=1.0), node("c", 4, False, x=2.0)])), NEW)
    assert [n["nodeId"] for n in drive] == ["b"]
    assert book.horizon
    assert [(s["nodeId"], s["released"]) for s in book.node_states()] == [("b", True), ("c", False)]
    assert [(s["edgeId"], s["released"]) for s in book.edge_states()] == [("a-b", True), ("b-c", False)]


def test_a_node_passed_takes_it_and_the_edge_before_it_off_the_states():
    book = taken(copy.deepcopy(THREE))
    book.passed(2, "b")
    assert [s["nodeId"] for s in book.node_states()] == ["c"]
    assert [s["edgeId"] for s in book.edge_states()] == ["b-c"]
    assert (book.last_node_id, book.last_node_seq) == ("b", 2)


def test_another_order_while_busy_is_refused_and_once_done_is_taken():
    book = taken(copy.deepcopy(THREE))
    second = check(order([node("c", 4, x=2.0)], order_id="o2"))
    assert refusal(book.decide, second, lambda n: True).error_type == "orderUpdateError"
    book.passed(4, "c")
    assert book.decide(second, lambda n: True) == NEW


def test_a_new_order_whose_first_node_is_away_is_a_no_route_error():
    found = refusal(OrderBook().decide, check(copy.deepcopy(THREE)), lambda n: False)
    assert found.error_type == "noRouteError"
    assert found.references == [("nodeId", "a")]


def test_updates_lower_refused_equal_ignored_higher_stitched_on_the_last_base_node():
    book = taken(order([node("a", 0, x=0.0), node("b", 2, x=1.0), node("c", 4, False, x=2.0)], update=3))
    lower = check(order([node("b", 2, x=1.0), node("c", 4, x=2.0)], update=2))
    assert refusal(book.decide, lower, None).error_type == "orderUpdateError"
    assert book.decide(check(order([node("a", 0, x=0.0)], update=3)), None) == IGNORE
    update = check(order([node("b", 2, x=1.0), node("c", 4, x=2.0), node("d", 6, False, x=3.0)], update=4))
    assert book.decide(update, None) == UPDATE
    drive = book.take(update, UPDATE)
    assert [n["nodeId"] for n in drive] == ["c"]
    assert [(s["nodeId"], s["released"]) for s in book.node_states()] == [("b", True), ("c", True), ("d", False)]
    assert [s["sequenceId"] for s in book.edge_states()] == [1, 3, 5]
    assert book.update_id == 4


def test_an_update_not_starting_at_the_last_base_node_is_refused():
    book = taken(order([node("a", 0, x=0.0), node("b", 2, x=1.0), node("c", 4, False, x=2.0)]))
    elsewhere = check(order([node("c", 4, x=2.0), node("d", 6, x=3.0)], update=1))
    found = refusal(book.decide, elsewhere, None)
    assert found.error_type == "orderUpdateError" and "must be the last base node b (2)" in str(found)


def test_an_update_after_the_order_is_done_starts_at_the_last_node_passed():
    book = taken(copy.deepcopy(THREE))
    book.passed(2, "b")
    book.passed(4, "c")
    update = check(order([node("c", 4, x=2.0), node("d", 6, x=3.0)], update=1))
    assert book.decide(update, None) == UPDATE
    assert [n["nodeId"] for n in book.take(update, UPDATE)] == ["d"]
    assert [s["nodeId"] for s in book.node_states()] == ["d"]


def test_a_dropped_order_keeps_its_ids_and_leaves_nothing_to_do():
    book = taken(copy.deepcopy(THREE))
    book.drop()
    assert not book.busy and book.order_id == "o1"


# the other messages ----------------------------------------------------------------

def test_timestamps_are_utc_to_the_millisecond():
    import datetime

    moment = datetime.datetime(2026, 11, 27, 17, 4, 5, 123456, tzinfo=datetime.timezone.utc)
    assert messages.timestamp(moment) == "2026-11-27T17:04:05.123Z"


def test_each_topic_counts_its_own_header_ids():
    headers = messages.Headers("2.0.0", "m", "s")
    assert [headers.stamp("state", {})["headerId"] for _ in range(3)] == [0, 1, 2]
    assert headers.stamp("connection", {})["headerId"] == 0


def test_an_update_piling_up_more_than_200_nodes_to_do_is_refused_and_keeps_the_order():
    book = taken(order([node("a", 0, x=0.0)] + [node("n{}".format(i), 2 * i, x=float(i)) for i in range(1, 150)]))
    nodes = [node("n149", 298, x=149.0)] + [node("m{}".format(i), 298 + 2 * i, x=149.0 + i) for i in range(1, 60)]
    update = check(order(nodes, update=1))
    assert book.decide(update, None) == UPDATE
    found = refusal(book.take, update, UPDATE)
    assert found.error_type == "orderError" and "208 nodes to do" in str(found)
    assert len(book.node_states()) == 149 and book.update_id == 0


def test_a_copy_kept_before_an_update_catches_up_with_what_the_robot_did_since():
    book = taken(copy.deepcopy(THREE))
    before = book.copy()
    book.passed(2, "b")
    assert before.caught_up(book).last_node_id == "b"
    assert [n["nodeId"] for n in before.nodes] == ["c"]
    book.drop()
    assert not before.caught_up(book).busy


def test_a_state_over_its_ceiling_leaves_out_action_states_then_errors(monkeypatch, caplog):
    import logging
    import types

    from flask_move_server.process.log_limits import Throttled
    from flask_move_server.vda5050 import vehicle

    monkeypatch.setattr(messages, "MAX_STATE", 2000)
    teller = types.SimpleNamespace(_oversize=Throttled(logging.getLogger("test"), "lines"))
    body = {"nodeStates": [{"nodeId": "n"}], "actionStates": [{"actionId": "a" * 1800}], "errors": [{"e": "x" * 300}]}
    assert vehicle.Vehicle._within_ceiling(teller, body)["actionStates"] == []
    assert vehicle.Vehicle._within_ceiling(teller, body)["errors"] == body["errors"]
    body["errors"] = [{"e": "x" * 1990}]
    smaller = vehicle.Vehicle._within_ceiling(teller, body)
    assert smaller["errors"] == [] and smaller["nodeStates"] == body["nodeStates"]
    assert "sent without its actionStates and errors" in caplog.text
    small = {"nodeStates": [], "actionStates": [{"actionId": "a"}], "errors": []}
    assert vehicle.Vehicle._within_ceiling(teller, small) == small
