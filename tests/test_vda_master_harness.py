"""The VDA 5050 tests' master (tests/vda_master.py: npm's vda-5050-lib MasterController in node),
checked against hand-written AGV messages on a real mosquitto, with no vehicle of ours.

What a vehicle test relies on: the AGV's messages come through as events, the ones the library
rejects come through as ``invalid`` (so that "no invalid event" means something), orders and
instant actions reach the AGV's topics with the library's header, and its callbacks follow the
AGV's states.
"""

import datetime
import json

import pytest

from tests.mqtt_broker import Broker, Listener
from tests.vda_master import Master, MasterError

MAKER, SERIAL = "acme", "r1"
BASE = "uagv/v2/{}/{}/".format(MAKER, SERIAL)


def now():
    return datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"


def header(header_id):
    return {"headerId": header_id, "timestamp": now(), "version": "2.0.0", "manufacturer": MAKER,
            "serialNumber": SERIAL}


def state(header_id, **fields):
    """A valid 2.0.0 state of an idle AGV, with ``fields`` changed."""
    message = dict(header(header_id), orderId="", orderUpdateId=0, lastNodeId="", lastNodeSequenceId=0,
                   nodeStates=[], edgeStates=[], driving=False, paused=False, newBaseRequest=False,
                   distanceSinceLastNode=0.0, operatingMode="AUTOMATIC", actionStates=[], errors=[],
                   information=[], loads=[], batteryState={"batteryCharge": 80.0, "charging": False},
                   safetyState={"eStop": "NONE", "fieldViolation": False},
                   agvPosition={"x": 1.0, "y": 2.0, "theta": 0.5, "mapId": "flat", "positionInitialized": True},
                   velocity={"vx": 0.0, "vy": 0.0, "omega": 0.0})
    message.update(fields)
    return message


def node(node_id, sequence_id, actions=()):
    return {"nodeId": node_id, "sequenceId": sequence_id, "released": True, "actions": list(actions),
            "nodePosition": {"x": float(sequence_id), "y": 0.0, "mapId": "flat"}}


def edge(edge_id, sequence_id, start, end):
    return {"edgeId": edge_id, "sequenceId": sequence_id, "released": True, "startNodeId": start,
            "endNodeId": end, "actions": []}


@pytest.fixture(scope="module")
def broker(tmp_path_factory):
    b = Broker(tmp_path_factory.mktemp("vda_broker"))
    yield b
    b.stop()


@pytest.fixture
def master(broker):
    m = Master()
    m.start(broker.port, MAKER, SERIAL)
    yield m
    m.close()
    assert m.proc.returncode == 0, m.stderr()


@pytest.fixture(scope="module")
def agv_client(broker):
    listener = Listener(broker, topics=(BASE + "order", BASE + "instantActions"))
    yield listener
    listener.close()


@pytest.fixture
def agv(agv_client):
    """The AGV's side, by hand: a paho client that hears its order and instantActions topics."""
    agv_client.clear()
    return agv_client


def send(agv, topic, message):
    agv.send(BASE + topic, message if isinstance(message, str) else json.dumps(message))


def test_start_names_the_topics_and_stop_ends_the_process(broker):
    with Master() as m:
        started = m.start(broker.port, MAKER, SERIAL)
        assert started["lib"] == "1.4.0" and started["vdaVersion"] == "2.0.0"
        assert started["topics"]["state"] == BASE + "state"
        assert started["topics"]["order"] == BASE + "order"
        assert m.last("link")["state"] == "online"
    assert m.proc.returncode == 0
    assert m.events()[-1]["event"] == "stopped"


def test_the_agvs_valid_messages_arrive_as_events(master, agv):
    send(agv, "connection", dict(header(0), connectionState="ONLINE"))
    send(agv, "state", state(0))
    send(agv, "visualization", dict(header(0), agvPosition=state(0)["agvPosition"],
                                    velocity={"vx": 0.1, "vy": 0.0, "omega": 0.0}))
    send(agv, "factsheet", dict(header(0), typeSpecification={
        "seriesName": "flask-move-server", "agvKinematic": "DIFF", "agvClass": "CARRIER", "maxLoadMass": 0.0,
        "localizationTypes": ["NATURAL"], "navigationTypes": ["AUTONOMOUS"]}))

    assert master.wait_event("connection")["connection"]["connectionState"] == "ONLINE"
    got = master.wait_event("state")
    assert got["state"]["batteryState"]["batteryCharge"] == 80.0
    assert got["agv"] == {"manufacturer": MAKER, "serialNumber": SERIAL}
    assert master.wait_event("visualization")["visualization"]["velocity"]["vx"] == 0.1
    assert master.wait_event("factsheet")["factsheet"]["typeSpecification"]["agvKinematic"] == "DIFF"
    master.assert_clean()


@pytest.mark.parametrize("what, bad, says", [
    ("no driving", lambda s: s.pop("driving"), "#/driving"),
    ("version 2.0", lambda s: s.update(version="2.0"), "Version"),
    ("a date that is not one", lambda s: s.update(timestamp="yesterday"), "#/timestamp"),
    ("an unknown operating mode", lambda s: s.update(operatingMode="AUTO"), "#/operatingMode"),
    ("a node state without released", lambda s: s.update(nodeStates=[{"nodeId": "n", "sequenceId": 0}]),
     "#/nodeStates"),
])
def test_a_state_the_library_rejects_shows_up_as_invalid(master, agv, what, bad, says):
    message = state(0)
    bad(message)
    send(agv, "state", message)
    send(agv, "state", state(1))  # a good one after: the master goes on

    master.wait_event("state")
    invalid = master.wait_event("invalid", topic="state")
    assert invalid["by"] == "vda-5050-lib"
    assert says in invalid["error"], invalid
    assert json.loads(invalid["payload"]) == message
    assert [e["state"]["headerId"] for e in master.events("state")] == [1]
    assert master.errors() == []


def test_not_json_and_a_wrong_agv_in_the_payload_show_up_as_invalid(master, agv):
    send(agv, "connection", '{"headerId": 0,')
    send(agv, "state", dict(state(0), serialNumber="r2"))

    broken = master.wait_event("invalid", topic="connection")
    assert broken["by"] == "vda-5050-lib" and broken["payload"] == '{"headerId": 0,'
    wrong = master.wait_event("invalid", topic="state")
    assert wrong["by"] == "harness" and "acme/r2" in wrong["error"], wrong


def test_an_order_reaches_the_agv_and_its_states_drive_the_callbacks(master, agv):
    order = {"orderId": "o1", "orderUpdateId": 0,
             "nodes": [node("n1", 0), node("n2", 2, [{"actionId": "a1", "actionType": "pick", "blockingType": "HARD",
                                                      "actionParameters": []}])],
             "edges": [edge("e1", 1, "n1", "n2")]}
    sent = master.order(order)
    assert sent["headerId"] == 0 and sent["version"] == "2.0.0" and sent["timestamp"].endswith("Z")
    received = agv.wait_json(BASE + "order")
    assert received == sent

    send(agv, "state", state(0, orderId="o1", orderUpdateId=0, lastNodeId="n1", lastNodeSequenceId=0, driving=True,
                             nodeStates=[{"nodeId": "n2", "sequenceId": 2, "released": True}],
                             edgeStates=[{"edgeId": "e1", "sequenceId": 1, "released": True}],
                             actionStates=[{"actionId": "a1", "actionType": "pick", "actionStatus": "WAITING"}]))
    first = master.wait_event("nodeTraversed", nodeId="n1")
    assert first["nextEdgeId"] == "e1" and first["nextNodeId"] == "n2" and first["stateHeaderId"] == 0
    traversing = master.wait_event("edgeTraversing", edgeId="e1")
    assert traversing["changes"]["driving"] is True and traversing["invocation"] == 1
    waiting = master.wait_event("actionStateChanged", actionId="a1")
    assert waiting["actionStatus"] == "WAITING" and waiting["target"] == {"nodeId": "n2", "sequenceId": 2}

    send(agv, "state", state(1, orderId="o1", orderUpdateId=0, lastNodeId="n2", lastNodeSequenceId=2,
                             actionStates=[{"actionId": "a1", "actionType": "pick", "actionStatus": "FINISHED"}]))
    master.wait_event("edgeTraversed", edgeId="e1")
    master.wait_event("nodeTraversed", nodeId="n2")
    master.wait_event("actionStateChanged", actionId="a1", actionStatus="FINISHED")
    done = master.wait_event("orderProcessed", orderId="o1")
    assert done["error"] is None and done["byCancelation"] is False and done["active"] is False
    master.assert_clean()


def test_instant_actions_and_their_outcomes(master, agv):
    sent = master.instant_actions([{"actionId": "i1", "actionType": "startPause", "blockingType": "HARD"},
                                   {"actionId": "i2", "actionType": "frobnicate", "blockingType": "NONE"}])
    assert agv.wait_json(BASE + "instantActions") == sent
    assert [a["actionId"] for a in sent["instantActions"]] == ["i1", "i2"]

    send(agv, "state", state(0, paused=True, actionStates=[
        {"actionId": "i1", "actionType": "startPause", "actionStatus": "FINISHED"}], errors=[
        {"errorType": "instantActionError", "errorLevel": "WARNING", "errorDescription": "unknown action",
         "errorReferences": [{"referenceKey": "actionId", "referenceValue": "i2"},
                             {"referenceKey": "topic", "referenceValue": "instantActions"}]}]))
    finished = master.wait_event("actionStateChanged", actionId="i1")
    assert finished["source"] == "instant" and finished["actionStatus"] == "FINISHED"
    failed = master.wait_event("actionError", actionId="i2")
    assert failed["error"]["errorType"] == "instantActionError"
    master.assert_clean()


def test_raw_messages_go_out_unchecked_and_bad_commands_answer_errors(master, agv):
    published = master.raw("order", {"orderId": "broken"}, header=True)
    received = agv.wait_json(BASE + "order")
    assert received["orderId"] == "broken" and received["version"] == "2.0.0" and "nodes" not in received
    assert published["mqttTopic"] == BASE + "order"
    master.raw("order", "{not json")
    agv.wait_last(BASE + "order", lambda text: text == "{not json")

    with pytest.raises(MasterError, match="Invalid VDA 5050 Order"):
        master.order({"orderId": "o2", "orderUpdateId": 0, "nodes": [], "edges": []})
    assert master.command({"cmd": "nonsense"})["event"] == "error"
    master.order({"orderId": "o3", "orderUpdateId": 0, "nodes": [node("n1", 0)], "edges": []})
    with pytest.raises(MasterError, match="discarded"):
        master.order({"orderId": "o3", "orderUpdateId": 0, "nodes": [node("n1", 0)], "edges": []})
    # One headerId counter for the topic: the raw order had 0, and the invalid order took 1 before
    # the library refused to send it, so the next order sent has 2 (the AGV never saw a 1).
    sent = agv.wait_last(BASE + "order", lambda text: '"o3"' in text, message="order o3 at the AGV")
    assert json.loads(sent)["headerId"] == 2
