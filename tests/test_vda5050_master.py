"""A fleet manager nobody here wrote drives the simulated robot: npm's vda-5050-lib ``MasterController``
(vdaVersion 2.0.0, tests/vda_master.py), over Debian's mosquitto, against ``flask-move-server --sim``.

The master validates each state it receives and tracks its orders by the robot's states only: an
order it reports processed is one the robot really reported done. Every message the robot sends is
checked against the standard's schemas as well (tests/vda_schemas.py).
"""

import json
import math
import signal

import pytest

from tests.conftest import stop_process, wait_for
from tests.mqtt_broker import Broker, retained_on
from tests.vda_fleet import BASE, Fleet, VdaSim, edges_of, node, where
from tests.vda_master import Master

MANUFACTURER, SERIAL = "flask-move-server", "robot"


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


@pytest.fixture(scope="module")
def master(broker):
    with Master() as m:
        m.start(broker.port, MANUFACTURER, SERIAL)
        yield m


@pytest.fixture(scope="module")
def sim(tmp_path_factory, broker, fleet, master):
    server = VdaSim(tmp_path_factory.mktemp("vda_master_sim"), broker)
    yield server
    stop_process(server.proc)


@pytest.fixture(autouse=True)
def clean(fleet, master):
    """Each test: the master took every message the robot sent, and each one meets the schemas."""
    yield
    master.assert_clean()
    assert fleet.unchecked_problems() == []


def here(master, sim):
    """The robot's place as its newest state (accepted by the master) says, standing and with no order
    (one a failed test left is canceled)."""
    last = master.last("state")
    if last is not None and last["state"]["nodeStates"]:
        master.instant_actions([{"actionId": "tidy-{}".format(master.mark()), "actionType": "cancelOrder",
                                 "blockingType": "HARD"}])
    wait_for(lambda: (lambda s: s is not None and "agvPosition" in s["state"] and not s["state"]["driving"]
                      and not s["state"]["nodeStates"])(master.last("state")), timeout=20,
             message="the robot standing, with no order")
    return where(master.last("state")["state"])


def order(order_id, nodes, update=0):
    return {"orderId": order_id, "orderUpdateId": update, "nodes": nodes, "edges": edges_of(nodes)}


def said_by(master, event):
    """The state that made the master fire ``event`` (its own event may come after ``event``)."""
    return master.wait_for(lambda e: e["event"] == "state" and e["state"]["headerId"] == event["stateHeaderId"],
                           message="state {}".format(event["stateHeaderId"]))["state"]


def near(state, x, y, tolerance=0.3):
    p = state["agvPosition"]
    return math.hypot(p["x"] - x, p["y"] - y) < tolerance


def test_the_master_drives_an_order_of_three_nodes(sim, master):
    start = here(master, sim)
    mark = master.mark()
    nodes = [node("m0", 0, position=start), node("sofa", 2),
             node("m2", 4, position={"x": 0.5, "y": 0.5, "mapId": start["mapId"]}, theta=0.0)]
    master.order(order("m-three", nodes))
    done = master.wait_event("orderProcessed", orderId="m-three", timeout=60, since=mark)
    assert (done["error"], done["byCancelation"], done["active"]) == (None, False, False)
    since = master.events()[mark:]
    assert [e["nodeId"] for e in since if e["event"] == "nodeTraversed"] == ["m0", "sofa", "m2"]
    assert [e["edgeId"] for e in since if e["event"] == "edgeTraversed"] == ["m0-sofa", "sofa-m2"]
    assert near(said_by(master, done), 0.5, 0.5)


def test_the_master_sends_a_horizon_then_its_update(sim, master):
    start = here(master, sim)
    mark = master.mark()
    first = dict(start, x=start["x"] - 0.5)
    second = dict(start, x=start["x"] - 0.5, y=start["y"] - 0.4)
    nodes = [node("u0", 0, position=start), node("u1", 2, position=first), node("u2", 4, False, position=second)]
    master.order(order("m-update", nodes))
    waiting = master.wait_event("orderProcessed", orderId="m-update", orderUpdateId=0, timeout=30, since=mark)
    assert waiting["active"] is True, "the base is done and only the horizon is left"
    assert near(said_by(master, waiting), first["x"], first["y"])
    update = [node("u1", 2, position=first), node("u2", 4, position=second)]
    master.order(order("m-update", update, update=1))
    done = master.wait_event("orderProcessed", orderId="m-update", orderUpdateId=1, timeout=30, since=mark)
    assert (done["error"], done["active"]) == (None, False)
    assert master.wait_event("nodeTraversed", nodeId="u2", since=mark)
    assert near(said_by(master, done), second["x"], second["y"])


def test_the_master_pauses_and_resumes_the_robot(sim, master):
    start = here(master, sim)
    mark = master.mark()
    nodes = [node("p0", 0, position=start), node("bedroom", 2)]
    master.order(order("m-pause", nodes))
    master.wait_for(lambda e: e["event"] == "state" and e["state"]["driving"], timeout=20, since=mark,
                    message="the robot driving")
    master.instant_actions([{"actionId": "m-pause-1", "actionType": "startPause", "blockingType": "HARD"}])
    master.wait_event("actionStateChanged", actionId="m-pause-1", actionStatus="FINISHED", since=mark)
    master.wait_for(lambda e: e["event"] == "state" and e["state"]["paused"] and not e["state"]["driving"],
                    since=mark, message="a paused, standing robot")
    master.instant_actions([{"actionId": "m-pause-2", "actionType": "stopPause", "blockingType": "HARD"}])
    master.wait_event("actionStateChanged", actionId="m-pause-2", actionStatus="FINISHED", since=mark)
    done = master.wait_event("orderProcessed", orderId="m-pause", timeout=60, since=mark)
    assert done["error"] is None and done["byCancelation"] is False


def test_the_master_cancels_an_order(sim, master):
    start = here(master, sim)
    mark = master.mark()
    nodes = [node("c0", 0, position=start), node("kitchen", 2)]
    master.order(order("m-cancel", nodes))
    master.wait_for(lambda e: e["event"] == "state" and e["state"]["driving"], timeout=20, since=mark,
                    message="the robot driving")
    master.instant_actions([{"actionId": "m-cancel-1", "actionType": "cancelOrder", "blockingType": "HARD"}])
    done = master.wait_event("orderProcessed", orderId="m-cancel", timeout=20, since=mark)
    assert done["byCancelation"] is True
    said = said_by(master, done)
    assert not said["driving"] and said["nodeStates"] == []


def test_the_master_sees_the_robot_vanish_when_its_server_is_killed(sim, master, broker):
    mark = master.mark()
    sim.proc.send_signal(signal.SIGKILL)
    sim.proc.wait()
    gone = master.wait_event("connection", timeout=30, since=mark,
                             message="the broker's last will for the robot")
    assert gone["connection"]["connectionState"] == "CONNECTIONBROKEN"
    assert json.loads(retained_on(broker, BASE + "connection"))["connectionState"] == "CONNECTIONBROKEN"
    assert json.dumps(gone["agv"]) == json.dumps({"manufacturer": MANUFACTURER, "serialNumber": SERIAL})
