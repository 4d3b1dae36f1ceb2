"""The robot as a VDA 5050 vehicle, against a real broker (Debian's mosquitto) and ``flask-move-server --sim``.

What a fleet manager relies on: the connection and factsheet retained, the state on each change,
orders driven node by node (base only; the horizon waited for; updates stitched on), refusals
that say why in ``errors`` and move nothing, and the instant actions. Every message the robot
sends in every test is checked against the standard's schemas (tests/vda_schemas.py). The npm
master of tests/test_vda5050_master.py drives the same robot as a fleet manager nobody here wrote.
"""

import json
import math
import os
import time

import pytest

from flask_move_server.sim import dwa
from tests.conftest import ROOT, stop_process, wait_for
from tests.mqtt_broker import Broker, retained_on
from tests.vda_fleet import BASE, Fleet, VdaSim, edges_of, error_types, node, where

DEMO = "demo"  # the mapId of the demo map, which `make demo` navigates on


@pytest.fixture(scope="module")
def broker(tmp_path_factory):
    b = Broker(tmp_path_factory.mktemp("broker"))
    yield b
    b.stop()


@pytest.fixture(scope="module")
def fleet(broker):
    listener = Fleet(broker)
    yield listener
    listener.close()


LEFT_ON_THE_BROKER = "left-on-the-broker"


@pytest.fixture(scope="module")
def sim(tmp_path_factory, broker, fleet):
    """The robot, started with an order retained on the broker (a master's mistake, or an attacker's)."""
    start = [node("r0", 0, position={"x": 0.0, "y": 0.0, "mapId": DEMO}), node("kitchen", 2)]
    left = dict(fleet.header(), orderId=LEFT_ON_THE_BROKER, orderUpdateId=0, nodes=start, edges=edges_of(start))
    fleet.send(BASE + "order", json.dumps(left), retain=True)
    try:
        server = VdaSim(tmp_path_factory.mktemp("vda_sim"), broker)
    finally:
        fleet.send(BASE + "order", "", retain=True)  # the broker forgets it
    yield server
    stop_process(server.proc)


@pytest.fixture(autouse=True)
def every_message_valid(fleet):
    """Whatever a test did, every message the robot sent meanwhile is valid VDA 5050."""
    yield
    assert fleet.unchecked_problems() == []


@pytest.fixture
def idle(sim, fleet):
    """The robot standing with no order: the e-stop released, a leftover order canceled."""
    sim.post("/estop/release")
    state = fleet.ask_state()
    if state["nodeStates"] or state["edgeStates"]:
        fleet.instant(("settle", "cancelOrder"))
    sim.post("/stop")
    return fleet.ask_state(lambda s: not s["driving"] and not s["nodeStates"] and "agvPosition" in s)


def true_pose(sim):
    return sim.status()["sim"]["true_pose"]


def standing(sim, seconds=0.6):
    before = true_pose(sim)
    time.sleep(seconds)
    after = true_pose(sim)
    return math.hypot(after["x"] - before["x"], after["y"] - before["y"]) < 0.02


def newest_run(sim):
    runs = sim.get("/runs").json()["runs"]
    return runs[0] if runs else None


def passed(fleet, order_id):
    """The nodes the robot reported passed for ``order_id``, in the order the states said so."""
    seen = []
    for state in fleet.states():
        if state["orderId"] == order_id and (not seen or seen[-1] != state["lastNodeId"]):
            seen.append(state["lastNodeId"])
    return seen


# connection, factsheet --------------------------------------------------------------

def test_an_order_retained_on_the_broker_moves_nothing_at_start_up(sim, fleet):
    assert fleet.ask_state(lambda s: "agvPosition" in s)["orderId"] == ""
    assert standing(sim) and sim.get("/runs").json()["runs"] == []
    assert all(s["orderId"] != LEFT_ON_THE_BROKER for s in fleet.states())


def test_the_robot_says_it_is_online_and_what_it_is_retained(sim, fleet, broker):
    fleet.state(message="a first state")
    status = json.loads(retained_on(broker, "homeassistant/sensor/robot/status/config"))
    assert status["availability_mode"] == "all"  # the connection's one last will is VDA 5050's: both count
    assert [a["topic"] for a in status["availability"]] == ["flask-move-server/robot/availability",
                                                            BASE + "connection"]
    assert json.loads(retained_on(broker, BASE + "connection"))["connectionState"] == "ONLINE"
    sheet = json.loads(retained_on(broker, BASE + "factsheet"))
    limits = dwa.load(os.path.join(ROOT, "config"))
    assert sheet["physicalParameters"]["speedMax"] == limits.max_vel_trans
    assert sheet["physicalParameters"]["accelerationMax"] == limits.acc_lim_x
    # config/costmap_common.yaml's footprint: 0.28 m long, 0.25 m wide
    assert (sheet["physicalParameters"]["length"], sheet["physicalParameters"]["width"]) == (0.28, 0.25)
    assert {a["actionType"] for a in sheet["protocolFeatures"]["agvActions"]} == {
        "cancelOrder", "startPause", "stopPause", "initPosition", "stateRequest", "factsheetRequest", "startCharging",
        "stopCharging"}
    assert all(a["actionScopes"] == ["INSTANT"] for a in sheet["protocolFeatures"]["agvActions"])


def test_the_state_says_where_the_robot_is_on_which_map_and_its_battery(sim, fleet, idle):
    position = idle["agvPosition"]
    truth = true_pose(sim)
    assert position["mapId"] == DEMO and position["positionInitialized"] is True
    assert math.hypot(position["x"] - truth["x"], position["y"] - truth["y"]) < 0.3
    battery = sim.status()["battery"]
    assert idle["batteryState"]["batteryCharge"] == pytest.approx(battery["percentage"], abs=1.0)
    assert idle["safetyState"] == {"eStop": "NONE", "fieldViolation": False}


def test_a_fleet_manager_asks_for_the_factsheet_and_gets_it(sim, fleet, idle):
    before = len(fleet.on(BASE + "factsheet"))
    fleet.instant(("fs-1", "factsheetRequest"))
    wait_for(lambda: len(fleet.on(BASE + "factsheet")) > before, message="the factsheet sent again")
    state = fleet.state(lambda s: any(a["actionId"] == "fs-1" for a in s["actionStates"]))
    assert [a["actionStatus"] for a in state["actionStates"] if a["actionId"] == "fs-1"] == ["FINISHED"]


# orders ----------------------------------------------------------------------------

def test_the_order_in_the_docs_sends_the_demo_robot_from_its_dock_to_the_kitchen(sim, fleet, idle):
    with open(os.path.join(ROOT, "docs", "fleet.md"), encoding="utf-8") as f:
        text = f.read()
    command = text[text.index("mosquitto_pub -t "):]
    topic = command.split()[2]
    payload = command[command.index("'") + 1:command.index("'", command.index("'") + 1)]
    assert topic == BASE + "order"
    fleet.send(topic, payload)
    done = fleet.state(lambda s: s["orderId"] == "first" and s["lastNodeId"] == "kitchen" and not s["driving"],
                       timeout=60, message="the robot in the kitchen")
    assert done["nodeStates"] == [] and done["errors"] == []
    kitchen = sim.get("/waypoints/kitchen").json()
    truth = true_pose(sim)
    assert math.hypot(truth["x"] - kitchen["x"], truth["y"] - kitchen["y"]) < 0.3


def test_an_order_of_three_nodes_is_driven_node_by_node(sim, fleet, idle):
    nodes = [node("here", 0, position=where(idle)), node("sofa", 2),
             node("by-the-dock", 4, position={"x": 0.4, "y": 0.0, "mapId": DEMO}, theta=0.0)]
    fleet.send_order("three", nodes, edges_of(nodes))
    taken = fleet.state(lambda s: s["orderId"] == "three", message="the order taken")
    assert [n["nodeId"] for n in taken["nodeStates"]] == ["sofa", "by-the-dock"]
    done = fleet.state(lambda s: s["orderId"] == "three" and not s["nodeStates"] and not s["driving"], timeout=60,
                       message="the order done")
    assert done["lastNodeId"] == "by-the-dock" and done["lastNodeSequenceId"] == 4 and done["errors"] == []
    assert passed(fleet, "three") == ["here", "sofa", "by-the-dock"]
    assert any(s["driving"] for s in fleet.states() if s["orderId"] == "three")
    truth = true_pose(sim)
    assert math.hypot(truth["x"] - 0.4, truth["y"]) < 0.3
    run = newest_run(sim)
    assert (run["trigger"], run["state"], run["route"]) == ("vda5050", "succeeded", "VDA 5050 order three")
    assert [v["name"] for v in run["visited"]] == ["sofa", "by-the-dock"]


def test_the_robot_waits_at_the_end_of_the_base_and_drives_on_with_the_update(sim, fleet, idle):
    start = where(idle)
    nodes = [node("h0", 0, position=start), node("h1", 2, position=dict(start, x=start["x"] - 0.5)),
             node("h2", 4, False, position=dict(start, x=start["x"] - 0.5, y=start["y"] + 1.0))]
    fleet.send_order("horizon", nodes, edges_of(nodes))
    waiting = fleet.state(lambda s: s["orderId"] == "horizon" and s["lastNodeId"] == "h1" and not s["driving"],
                          timeout=30, message="the robot at the last base node")
    assert [(n["nodeId"], n["released"]) for n in waiting["nodeStates"]] == [("h2", False)]
    assert [(e["edgeId"], e["released"]) for e in waiting["edgeStates"]] == [("h1-h2", False)]
    assert standing(sim), "the horizon is not driven"
    assert newest_run(sim)["message"] == "Waiting at h1 for the next stops of the order."
    fleet.send_order("horizon", nodes[:1], [], update=0)  # the same update again: ignored
    assert fleet.ask_state()["errors"] == [] and standing(sim, 0.5)
    update = [node("h1", 2, position=nodes[1]["nodePosition"]), node("h2", 4, position=nodes[2]["nodePosition"])]
    fleet.send_order("horizon", update, edges_of(update), update=1)
    done = fleet.state(lambda s: s["orderUpdateId"] == 1 and s["lastNodeId"] == "h2" and not s["driving"],
                       timeout=30, message="the update driven")
    assert done["nodeStates"] == [] and done["edgeStates"] == []
    assert newest_run(sim)["state"] == "succeeded"
    fleet.send_order("horizon", update, edges_of(update), update=0)  # lower than the one in force
    refused = fleet.state(lambda s: "orderUpdateError" in error_types(s), message="the lower update refused")
    assert refused["orderUpdateId"] == 1 and standing(sim, 0.5)


# refusals ----------------------------------------------------------------------------

def _far(state):
    p = where(state)
    return dict(p, x=p["x"] + 3.0)


REFUSED = {
    "edges that do not join the nodes": (
        "validationError", lambda s: dict(nodes=[node("a", 0, position=where(s)), node("sofa", 2)], edges=[
            {"edgeId": "e", "sequenceId": 1, "released": True, "startNodeId": "x", "endNodeId": "sofa",
             "actions": []}])),
    "another map": ("orderError", lambda s: dict(nodes=[node("a", 0, position=dict(where(s), mapId="cellar"))],
                                                 edges=[])),
    "an action the robot cannot do": ("orderError", lambda s: dict(nodes=[
        node("a", 0, position=where(s)), dict(node("sofa", 2), actions=[
            {"actionId": "p", "actionType": "pick", "blockingType": "HARD"}])], edges=None)),
    "a first node away from the robot": ("noRouteError", lambda s: dict(nodes=[node("a", 0, position=_far(s)),
                                                                               node("sofa", 2)], edges=None)),
    "a node naming no waypoint": ("orderError", lambda s: dict(nodes=[node("a", 0, position=where(s)),
                                                                      node("pantry", 2)], edges=None)),
}


def _raw_order(fleet, order_id, parts):
    edges = parts["edges"] if parts["edges"] is not None else edges_of(parts["nodes"])
    message = dict(fleet.header(), orderId=order_id, orderUpdateId=0, nodes=parts["nodes"], edges=edges)
    fleet.raw("order", json.dumps(message))


def _moved_nothing(sim, runs_before):
    assert standing(sim, 0.5)
    motors = sim.status()["motors"]
    assert (motors["left"], motors["right"]) == (0.0, 0.0)
    assert len(sim.get("/runs").json()["runs"]) == runs_before
    assert sim.get("/health").status_code == 200


@pytest.mark.parametrize("case", sorted(REFUSED))
def test_a_refused_order_says_why_and_moves_nothing(sim, fleet, idle, case):
    error_type, parts = REFUSED[case]
    runs_before = len(sim.get("/runs").json()["runs"])
    _raw_order(fleet, "refused-" + case.replace(" ", "-"), parts(idle))
    state = fleet.state(lambda s: error_type in error_types(s), message="the {} refused".format(case))
    assert state["nodeStates"] == [] and not state["driving"]
    assert [e["errorLevel"] for e in state["errors"]] == ["WARNING"] * len(state["errors"])
    _moved_nothing(sim, runs_before)


@pytest.mark.parametrize("payload, words", [
    ("{not json", "Not JSON"),
    ("x" * (1024 * 1024), "larger than the 262144 bytes"),
    ("[" * 100000, "nested too deep"),
])
def test_malformed_or_huge_messages_are_validation_errors(sim, fleet, idle, payload, words):
    runs_before = len(sim.get("/runs").json()["runs"])
    fleet.raw("order", payload)
    state = fleet.state(lambda s: any(words in e["errorDescription"] for e in s["errors"]),
                        message="the message refused")
    assert "validationError" in error_types(state)
    _moved_nothing(sim, runs_before)
    fleet.raw("instantActions", payload)  # the instant actions' topic alike
    wait_for(lambda: sum(words in e["errorDescription"] for e in fleet.ask_state()["errors"]) >= 1,
             message="instantActions refused too")


def test_an_order_taken_clears_the_warnings_of_those_refused_before(sim, fleet, idle):
    fleet.raw("order", "{broken")
    fleet.state(lambda s: "validationError" in error_types(s))
    nodes = [node("c0", 0, position=where(idle))]
    fleet.send_order("clean", nodes, [])
    state = fleet.state(lambda s: s["orderId"] == "clean")
    assert state["errors"] == [] and state["lastNodeId"] == "c0" and state["nodeStates"] == []


def test_another_order_while_one_is_under_way_is_refused(sim, fleet, idle):
    nodes = [node("b0", 0, position=where(idle)), node("kitchen", 2)]
    fleet.send_order("busy", nodes, edges_of(nodes))
    fleet.state(lambda s: s["orderId"] == "busy" and s["driving"], message="driving the first order")
    other = [node("o0", 0, position=where(idle))]
    fleet.send_order("intruder", other, [])
    state = fleet.state(lambda s: "orderUpdateError" in error_types(s))
    assert state["orderId"] == "busy" and state["driving"]


# instant actions ---------------------------------------------------------------------

def _action(state, action_id):
    return next((a for a in state["actionStates"] if a["actionId"] == action_id), None)


def test_pause_stops_the_robot_where_it_is_and_stop_pause_drives_on(sim, fleet, idle):
    nodes = [node("p0", 0, position=where(idle)), node("bedroom", 2)]
    fleet.send_order("pausing", nodes, edges_of(nodes))
    fleet.state(lambda s: s["orderId"] == "pausing" and s["driving"], message="driving")
    fleet.instant(("pause-1", "startPause"))
    paused = fleet.state(lambda s: s["paused"] and not s["driving"], message="paused and standing")
    assert _action(paused, "pause-1")["actionStatus"] == "FINISHED"
    assert [n["nodeId"] for n in paused["nodeStates"]] == ["bedroom"]
    assert standing(sim)
    assert newest_run(sim)["state"] == "paused"
    fleet.instant(("resume-1", "stopPause"))
    going = fleet.state(lambda s: s["driving"] and (_action(s, "resume-1") or {}).get("actionStatus") == "FINISHED",
                        message="driving on to the bedroom")
    assert going["paused"] is False
    wait_for(lambda: not standing(sim, 0.3), timeout=10, message="the robot moving again")
    assert newest_run(sim)["state"] == "running"


def test_cancel_order_stops_the_robot_and_drops_the_order_then_there_is_none_to_cancel(sim, fleet, idle):
    nodes = [node("k0", 0, position=where(idle)), node("office", 2)]
    fleet.send_order("canceled", nodes, edges_of(nodes))
    fleet.state(lambda s: s["orderId"] == "canceled" and s["driving"], message="driving")
    fleet.instant(("cancel-1", "cancelOrder"))
    state = fleet.state(lambda s: (_action(s, "cancel-1") or {}).get("actionStatus") == "FINISHED")
    assert not state["driving"]
    assert state["nodeStates"] == [] and state["edgeStates"] == [] and state["orderId"] == "canceled"
    assert standing(sim)
    assert newest_run(sim)["state"] == "canceled"
    fleet.instant(("cancel-2", "cancelOrder"))
    state = fleet.state(lambda s: _action(s, "cancel-2") is not None)
    assert _action(state, "cancel-2")["actionStatus"] == "FAILED"
    error = next(e for e in state["errors"] if e["errorType"] == "noOrderToCancel")
    assert error["errorLevel"] == "WARNING"
    assert error["errorReferences"] == [{"referenceKey": "actionId", "referenceValue": "cancel-2"}]


def test_the_robot_stopped_on_the_robot_ends_the_order_and_says_so(sim, fleet, idle):
    nodes = [node("s0", 0, position=where(idle)), node("kitchen", 2)]
    fleet.send_order("stopped", nodes, edges_of(nodes))
    fleet.state(lambda s: s["orderId"] == "stopped" and s["driving"], message="driving")
    assert sim.post("/estop").status_code == 200
    state = fleet.state(lambda s: s["safetyState"]["eStop"] == "REMOTE" and not s["nodeStates"] and not s["driving"])
    assert "orderError" in error_types(state)
    assert newest_run(sim)["state"] == "canceled"
    sim.post("/estop/release")
    assert fleet.state(lambda s: s["safetyState"]["eStop"] == "NONE")


def test_init_position_on_the_active_map_relocalizes_and_on_another_fails(sim, fleet, idle):
    truth = true_pose(sim)
    fleet.instant(("init-1", "initPosition", {"x": truth["x"], "y": truth["y"], "theta": truth["yaw"],
                                              "mapId": "cellar", "lastNodeId": "x"}))
    state = fleet.state(lambda s: _action(s, "init-1") is not None)
    assert _action(state, "init-1")["actionStatus"] == "FAILED"
    assert "not the map the robot navigates on (demo)" in _action(state, "init-1")["resultDescription"]
    fleet.instant(("init-2", "initPosition", {"x": truth["x"], "y": truth["y"], "theta": truth["yaw"],
                                              "mapId": DEMO, "lastNodeId": "at-home"}))
    fleet.instant(("init-nan", "initPosition", {"x": float("nan"), "y": 0.0, "theta": 0.0, "mapId": DEMO}))
    state = fleet.state(lambda s: _action(s, "init-nan") is not None)
    assert _action(state, "init-nan")["actionStatus"] == "FAILED"
    state = fleet.state(lambda s: _action(s, "init-2") is not None, timeout=20)
    assert _action(state, "init-2")["actionStatus"] == "FINISHED", _action(state, "init-2")
    assert fleet.state(lambda s: s["lastNodeId"] == "at-home")["agvPosition"]["positionInitialized"]


def test_an_unknown_instant_action_fails_and_says_so(sim, fleet, idle):
    fleet.instant(("lift-1", "liftFork"))
    state = fleet.state(lambda s: _action(s, "lift-1") is not None)
    assert _action(state, "lift-1")["actionStatus"] == "FAILED"
    assert any("liftFork" in e["errorDescription"] for e in state["errors"])
    assert standing(sim, 0.5)


def _instant_raw(fleet, actions):
    fleet.raw("instantActions", json.dumps(dict(fleet.header(), actions=actions)))


def _state_bytes(fleet):
    return max(len(text.encode("utf-8")) for _t, text, _r in fleet.on(BASE + "state")[-20:])


def test_instant_actions_with_ids_past_the_factsheets_length_are_refused_without_echo(sim, fleet, idle):
    """Issue 34: 60 such messages (255 KB each) made every state 17 MB and stalled /stop and the motors."""
    long = "x" * 2400
    for n in range(6):  # each message ~250 KB: 50 actions of an id and a type of 2400 characters
        _instant_raw(fleet, [{"actionId": "{}-{}{}".format(n, i, long), "actionType": long + str(i),
                              "blockingType": "NONE"} for i in range(50)])
    state = fleet.ask_state(lambda s: any("longer than 200 characters" in e["errorDescription"]
                                          for e in s["errors"]))
    assert not any(long in a["actionId"] or long in a["actionType"] for a in state["actionStates"])
    assert long not in json.dumps(state["errors"])
    assert _state_bytes(fleet) < 16 * 1024
    assert sim.post("/stop").status_code == 200 and standing(sim, 0.3)


def test_many_long_unknown_instant_actions_keep_the_state_bounded(sim, fleet, idle):
    ids = ["é" * 190 + "{:05d}".format(i) for i in range(300)]  # 200 characters, twice the bytes
    for chunk in range(0, 300, 50):
        _instant_raw(fleet, [{"actionId": i, "actionType": "ü" * 190 + i[-10:], "blockingType": "NONE"}
                             for i in ids[chunk:chunk + 50]])
    state = fleet.ask_state(lambda s: _action(s, ids[-1]) is not None, message="the last action told")
    assert _action(state, ids[-1])["actionStatus"] == "FAILED"
    assert _action(state, ids[0]) is None  # the oldest left out
    kept = [a for a in state["actionStates"] if a["actionId"] in ids]
    assert 10 <= len(kept) < 50  # bounded in bytes (48 KB), before the 50 states the count allows
    assert len(json.dumps(state["errors"], ensure_ascii=False).encode("utf-8")) <= 16 * 1024
    assert _state_bytes(fleet) < 80 * 1024


def test_init_position_with_a_long_map_or_node_id_is_refused(sim, fleet, idle):
    here = where(idle)
    fleet.instant(("init-long", "initPosition", {"x": here["x"], "y": here["y"], "theta": 0.0,
                                                "mapId": DEMO, "lastNodeId": "n" * 5000}))
    state = fleet.state(lambda s: _action(s, "init-long") is not None)
    assert _action(state, "init-long")["actionStatus"] == "FAILED"
    assert state["lastNodeId"] != "n" * 5000 and "n" * 300 not in json.dumps(state)


@pytest.mark.parametrize("who", [{"serialNumber": "robot-in-the-next-room"}, {"manufacturer": "someone-else"}])
def test_an_order_or_instant_action_for_another_vehicle_is_refused_and_moves_nothing(sim, fleet, idle, who):
    """Issue 34, item 6: an order whose header names another serialNumber (a master's mix-up, or a client
    that should not publish here) was driven."""
    runs_before = len(sim.get("/runs").json()["runs"])
    kitchen = [node("r0", 0, position=where(idle)), node("kitchen", 2)]
    fleet.raw("order", json.dumps(dict(fleet.header(), orderId="not-mine", orderUpdateId=0, nodes=kitchen,
                                       edges=edges_of(kitchen), **who)))
    state = fleet.state(lambda s: any("order is addressed to another vehicle" in e["errorDescription"]
                                      for e in s["errors"]), message="the order for another vehicle refused")
    assert "validationError" in error_types(state) and state["orderId"] != "not-mine"
    assert "robot-in-the-next-room" not in json.dumps(state) and "someone-else" not in json.dumps(state)
    fleet.raw("instantActions", json.dumps(dict(fleet.header(), actions=[
        {"actionId": "pause-not-mine", "actionType": "startPause", "blockingType": "HARD"}], **who)))
    state = fleet.state(lambda s: any("instantActions is addressed to another vehicle" in e["errorDescription"]
                                      for e in s["errors"]), message="the instant action for another vehicle refused")
    assert not state["paused"] and "pause-not-mine" not in json.dumps(state["actionStates"])
    _moved_nothing(sim, runs_before)


# the owner's commands beside the fleet manager's -------------------------------------------

def test_the_owner_cannot_skip_a_node_of_the_fleet_managers_order(sim, fleet, idle):
    nodes = [node("q0", 0, position=where(idle)), node("sofa", 2)]
    fleet.send_order("no-skip", nodes, edges_of(nodes))
    fleet.state(lambda s: s["orderId"] == "no-skip" and s["driving"], message="driving")
    r = sim.post("/runs/{}/skip".format(newest_run(sim)["id"]))
    assert r.status_code == 409 and "fleet manager" in r.json()["message"]
    done = fleet.state(lambda s: s["orderId"] == "no-skip" and s["lastNodeId"] == "sofa" and not s["driving"],
                       timeout=60, message="the order driven to its end")
    assert done["nodeStates"] == []


def test_a_pause_the_owner_resumes_is_no_longer_told_as_paused(sim, fleet, idle):
    nodes = [node("w0", 0, position=where(idle)), node("bedroom", 2)]
    fleet.send_order("owner-resumes", nodes, edges_of(nodes))
    fleet.state(lambda s: s["orderId"] == "owner-resumes" and s["driving"], message="driving")
    fleet.instant(("pause-o", "startPause"))
    fleet.state(lambda s: s["paused"] and not s["driving"], message="paused")
    assert sim.post("/runs/{}/resume".format(newest_run(sim)["id"])).status_code == 200
    state = fleet.state(lambda s: s["driving"], message="driving again")
    assert state["paused"] is False


def test_an_order_waiting_for_its_release_ends_when_the_owner_sends_the_robot_elsewhere(sim, fleet, idle):
    start = where(idle)
    nodes = [node("v0", 0, position=start), node("v1", 2, False, position=dict(start, x=start["x"] + 0.5))]
    fleet.send_order("waiting", nodes, edges_of(nodes))
    waiting = fleet.state(lambda s: s["orderId"] == "waiting" and s["nodeStates"])
    assert waiting["nodeStates"][0]["released"] is False
    assert waiting["nodeStates"][0]["nodePosition"]["theta"] == 0.0  # none sent: the way from v0, +x
    assert sim.post("/goto", {"name": "sofa"}).status_code == 202
    ended = fleet.state(lambda s: not s["nodeStates"] and "orderError" in error_types(s),
                        message="the order ended on the robot")
    assert any("on its way to sofa" in e["errorDescription"] for e in ended["errors"])
    sim.post("/stop")


# shutdown -------------------------------------------------------------------------------

def test_start_charging_docks_until_it_charges_and_stop_charging_backs_off(sim, fleet, idle):
    fleet.instant(("charge-1", "startCharging"))
    fleet.state(lambda s: (_action(s, "charge-1") or {}).get("actionStatus") == "RUNNING")
    assert sim.status()["dock"]["state"] in ("going", "approaching", "charging")
    state = fleet.state(lambda s: _action(s, "charge-1")["actionStatus"] != "RUNNING", timeout=120)
    assert _action(state, "charge-1")["actionStatus"] == "FINISHED", _action(state, "charge-1")
    assert _action(state, "charge-1")["resultDescription"] == "Charging at dock."
    assert fleet.state(lambda s: s["batteryState"]["charging"], timeout=10)["batteryState"]["charging"] is True
    fleet.instant(("off-1", "stopCharging"))
    state = fleet.state(lambda s: (_action(s, "off-1") or {}).get("actionStatus") in ("FINISHED", "FAILED"),
                        timeout=60)
    assert _action(state, "off-1")["actionStatus"] == "FINISHED" and sim.status()["dock"]["state"] == "undocked"
    fleet.instant(("off-2", "stopCharging"))
    state = fleet.state(lambda s: _action(s, "off-2") is not None)
    assert _action(state, "off-2")["actionStatus"] == "FAILED"
    assert "not on a charger" in _action(state, "off-2")["resultDescription"]


def test_a_clean_stop_says_offline_retained(sim, broker):
    """The module's last test: its robot stops."""
    stop_process(sim.proc)
    assert sim.proc.returncode == 0
    assert json.loads(retained_on(broker, BASE + "connection"))["connectionState"] == "OFFLINE"
