"""VDA 5050 on the robot's MQTT connection: an order's way to move_base, the cost at rest, the traffic driving.

    .venv/bin/python bench/bench_vda5050.py [--orders 50] [--spacing 0.3] [--settle 10]
        [--cpu-seconds 30] [--cpu-repeat 2] [--drives 1] [--skip latency,cpu,drive]

A real broker (Debian's mosquitto on a free port, ``tests/mqtt_broker.py``) and real
``flask-move-server --sim`` processes (speed factor 1, the demo map and waypoints, each its own ROS
master, MQTT with Home Assistant's discovery on, ``mqtt.vda5050.enabled`` as each row says). A
fleet manager is played by the tests' ``Fleet`` (tests/vda_fleet.py: a paho client sending orders
and instant actions at QoS 0), subscribed at QoS 1 to the robot's state, visualization, connection
and factsheet (not to ``<base>/#``, its own orders too: see VDA_OUT), its socket with ``TCP_NODELAY``
(bench_mqtt found paho's Nagle delaying a client's message up to 40 ms while its PUBACK for a state
is unacknowledged: the client's cost, not the robot's); Home Assistant by a paho client subscribed
to everything the robots send, which also counts it.

1. **An order to its goal at move_base**: a new order of two nodes (the first where the robot stands,
   read from its last state's ``agvPosition``; the second 1 m from the robot's first place, along x
   and along y in turns, so each is a new goal), published by the fleet client, until the goal
   arrives on the sim's ``/move_base/goal``, seen by a rospy subscriber here (bench_mqtt's
   ``GoalWatch``); and until the state saying the order is taken reaches the fleet client. Then an
   instant action ``cancelOrder``, its ``FINISHED`` state and the robot standing (move_base idle)
   are waited for, and ``--spacing`` s: every order finds the vehicle idle with no run, as after an
   order driven to its end, without driving metres between samples. For reference the same with
   ``POST /goto {x, y}`` on one keep-alive connection, then ``POST /stop``. ``--orders`` each, two
   of a way then two of the next, in turns.
2. **CPU at rest**: three servers side by side over the same windows (the machine's load falls on
   all alike), MQTT and Home Assistant on in each: VDA 5050 on in the first, off in the other two
   (the second only to show how far two identical servers differ). User + system CPU from
   ``/proc/<pid>/stat`` over ``--cpu-seconds``, ``--cpu-repeat`` windows after ``--settle`` s;
   mosquitto's; the ``vda5050-state`` thread's own and the MQTT threads' (named by ``py-spy dump``,
   timed in ns from ``/proc/<pid>/task/<tid>/schedstat``, as bench_mqtt does); the messages per
   second the robot published on its VDA topics.
3. **While driving**: an order of two nodes, ~3 m out to the kitchen's side of the flat, then one
   back (``--drives`` times), each from its publishing to the state saying it is done: messages and
   bytes per second on each VDA topic (and Home Assistant's, for comparison), the server's CPU and
   the ``vda5050-state`` thread's.

Every message the robot sent on the VDA topics during parts 1 and 3 is checked against the
standard's schemas (tests/vda_schemas.py) at the end. Prints markdown tables (docs/performance.md,
section "VDA 5050").
"""

import argparse
import json
import os
import pathlib
import shutil
import socket
import statistics
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)

from bench_mqtt import (  # noqa: E402
    MQTT_THREADS,
    GoalWatch,
    Sim,
    _mosquitto_version,
    mqtt_tids,
    percentile,
    thread_cpu,
)
from bench_sim import cpu_seconds  # noqa: E402

from tests.conftest import stop_process, wait_for  # noqa: E402
from tests.mqtt_broker import Broker, Listener  # noqa: E402
from tests.vda_fleet import Fleet, edges_of, node, where  # noqa: E402
from tests.vda_schemas import check  # noqa: E402

VDA_ON = "  vda5050:\n    enabled: true\n"
STATE_THREAD = "vda5050-state"
STEPS = ((1.0, 0.0), (0.0, 1.0))  # m from the robot's first place (the dock): the orders' second nodes, in turns
DRIVE = ((1.5, 0.4), (3.0, 0.8))  # m from the dock: the nodes driven out (back: the other way), free on the demo map
VDA_OUT = ("state", "visualization", "connection", "factsheet")  # the robot's VDA topics
# A client subscribed to the topic it publishes QoS 0 orders on (``<base>/#``) gets each back and
# answers nothing, so its kernel delays the ACK (40 ms); mosquitto's socket to it (Nagle on: no
# set_tcp_nodelay) then holds the robot's next state, the one saying the order is taken, until that
# ACK: 40-45 ms instead of 7-15 (diagnosed while writing this bench). A master subscribes to the
# vehicles' out-topics, so the clients here do so too.


def vda_base(name):
    return "uagv/v2/flask-move-server/{}/".format(name)


def ha_base(name):
    return "flask-move-server/{}/".format(name)


# the fleet manager -----------------------------------------------------------------------------

def fleet_client(broker, name):
    """The tests' fleet manager on robot ``name``'s topics, its socket with Nagle's algorithm off,
    subscribed only to what the robot sends (not to its own orders: see VDA_OUT)."""
    fleet = Fleet(broker, base=vda_base(name))
    fleet.client.socket().setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    fleet._subscribed.clear()
    fleet.client.subscribe([(fleet.base + kind, 1) for kind in VDA_OUT])
    wait_for(fleet._subscribed.is_set, message="the fleet's subscriptions")
    fleet.client.unsubscribe(fleet.base + "#")
    time.sleep(0.2)  # the unsubscription done
    return fleet


def home_client(broker):
    """Home Assistant (and a bench counting): everything the robots send, none of the VDA inputs (VDA_OUT)."""
    return Listener(broker, topics=("flask-move-server/#", "homeassistant/#")
                    + tuple("uagv/+/+/+/" + kind for kind in VDA_OUT))


def state_since(fleet, after, predicate, timeout=20, message="a state"):
    """``(arrival time, state)``: the first state the fleet got at or after ``after`` that ``predicate`` holds for."""
    def found():
        return next(((t, s) for t, s in ((t, json.loads(text)) for t, text, _r in fleet.on(fleet.base + "state")
                                         if t >= after) if predicate(s)), None)
    return wait_for(found, timeout=timeout, message=message)


def order_message(fleet, order_id, positions):
    """A new order through ``positions`` (nodePositions; the first where the robot stands), all released."""
    nodes = [node("n{}".format(k), 2 * k, position=p) for k, p in enumerate(positions)]
    message = dict(fleet.header(), orderId=order_id, orderUpdateId=0, nodes=nodes, edges=edges_of(nodes))
    check("order", message)
    return json.dumps(message)


def offset(place, dx, dy):
    return {"x": round(place["x"] + dx, 3), "y": round(place["y"] + dy, 3), "mapId": place["mapId"]}


def move_base_idle(sim):
    wait_for(lambda: sim.get("/status").json()["navigation"]["state"] != "active", timeout=20,
             message="move_base idle")


# 1. an order to move_base ----------------------------------------------------------------------

WAYS = (("vda", "VDA 5050 order: paho → mosquitto → server"), ("http", "HTTP `POST /goto {x, y}`"))


def vda_order(fleet, watch, order_id, target):
    """One order to ``target``, canceled once taken: (ms to its goal at move_base, ms to its state back)."""
    here = where(fleet.state(lambda s: "agvPosition" in s))
    payload = order_message(fleet, order_id, [here, target])
    started = time.monotonic()
    fleet.client.publish(fleet.base + "order", payload, qos=0)
    goal = watch.arrival(target["x"], started)
    back, _ = state_since(fleet, started, lambda s: s["orderId"] == order_id and bool(s["nodeStates"]),
                          message="the order's state")
    canceled = time.monotonic()
    fleet.instant(("cancel-" + order_id, "cancelOrder"))
    state_since(fleet, canceled, lambda s: not s["nodeStates"] and any(
        a["actionType"] == "cancelOrder" and a["actionStatus"] == "FINISHED" for a in s["actionStates"]),
        message="the cancelOrder finished")
    return (goal - started) * 1e3, (back - started) * 1e3


def http_goto(sim, watch, target):
    """``POST /goto`` to ``target``, then ``/stop``: (ms to its goal at move_base, ms to the answer)."""
    started = time.monotonic()
    status, body = sim.post_fast("/goto", {"x": target["x"], "y": target["y"]})
    answer = time.monotonic()
    if status != 202:
        raise RuntimeError("POST /goto answered {}: {}".format(status, body))
    goal = watch.arrival(target["x"], started)
    sim.post_fast("/stop")
    return (goal - started) * 1e3, (answer - started) * 1e3


def order_latency(sim, fleet, watch, origin, orders, spacing, tag="o"):
    """ms per way (WAYS): ``{way: ([to move_base], [to the state or the answer])}``."""
    trips = {way: ([], []) for way, _ in WAYS}
    for i in range(len(WAYS) * orders):
        way = WAYS[(i // 2) % len(WAYS)][0]
        target = offset(origin, *STEPS[i % 2])
        if way == "vda":
            goal, back = vda_order(fleet, watch, "{}{}".format(tag, i), target)
        else:
            goal, back = http_goto(sim, watch, target)
        trips[way][0].append(goal)
        trips[way][1].append(back)
        move_base_idle(sim)
        time.sleep(spacing)
    return trips


# 2. CPU at rest --------------------------------------------------------------------------------

def traffic(listener, prefix, start, end):
    """``{topic under prefix: (messages, bytes)}`` the listener got from ``start`` to ``end``."""
    out = {}
    with listener._lock:
        seen = [(top, text) for t, top, text, _r in listener.messages if start <= t < end and top.startswith(prefix)]
    for top, text in seen:
        n, size = out.get(top[len(prefix):], (0, 0))
        out[top[len(prefix):]] = (n + 1, size + len(text.encode("utf-8")))
    return out


def thread_shares(pid, tids, before, passed):
    """``{thread name: % of one core}`` since ``before`` (thread_cpu's)."""
    now = thread_cpu(pid)
    return {name: 100.0 * (now.get(tid, 0.0) - before[tid]) / passed for tid, name in tids.items() if tid in before}


def idle_window(servers, broker, home, tids, seconds):
    """One window: each server's and mosquitto's CPU, the VDA server's and an off one's threads, its VDA messages/s."""
    procs = [s.proc.pid for s in servers] + [broker.proc.pid]
    before = [cpu_seconds(p) for p in procs]
    threads0 = [thread_cpu(s.proc.pid) for s in servers[:2]]
    start = time.monotonic()
    time.sleep(seconds)
    end = time.monotonic()
    passed = end - start
    shares = [100.0 * (cpu_seconds(p) - b) / passed for p, b in zip(procs, before)]
    threads = [thread_shares(s.proc.pid, t, t0, passed) for s, t, t0 in zip(servers, tids, threads0)]
    sent = traffic(home, vda_base("vda"), start, end)
    rates = {kind: n / passed for kind, (n, _b) in sent.items()}
    return shares, threads, rates


def idle_cpu(servers, broker, home, seconds, repeat):
    """``repeat`` windows of idle_window; threads named by py-spy (VDA on: vda5050-state and MQTT's)."""
    tids = [mqtt_tids(servers[0].proc.pid, (STATE_THREAD,) + MQTT_THREADS), mqtt_tids(servers[1].proc.pid)]
    return [idle_window(servers, broker, home, tids, seconds) for _ in range(repeat)]


# 3. while driving ------------------------------------------------------------------------------

def drive_order(sim, fleet, home, tids, order_id, positions):
    """Drive an order through ``positions`` to its end: (seconds, VDA traffic, HA traffic, server CPU %, threads %)."""
    payload = order_message(fleet, order_id, positions)
    pid = sim.proc.pid
    cpu0, threads0 = cpu_seconds(pid), thread_cpu(pid)
    start = time.monotonic()
    fleet.client.publish(fleet.base + "order", payload, qos=0)
    state_since(fleet, start, lambda s: s["orderId"] == order_id and s["nodeStates"], message="the order taken")
    end, last = state_since(fleet, start, lambda s: s["orderId"] == order_id and not s["nodeStates"]
                            and not s["driving"], timeout=120, message="the order done")
    if last["lastNodeId"] != "n{}".format(len(positions) - 1) or last["errors"]:
        raise RuntimeError("order {} did not arrive: {}".format(order_id, last))
    time.sleep(0.05)  # the visualization sent with the last state is counted too
    passed = end - start
    cpu = 100.0 * (cpu_seconds(pid) - cpu0) / (time.monotonic() - start)
    threads = thread_shares(pid, tids, threads0, time.monotonic() - start)
    return (passed, traffic(home, fleet.base, start, end + 0.05),
            traffic(home, ha_base("bench-robot"), start, end + 0.05), cpu, threads)


def drives(sim, fleet, home, origin, rounds):
    """``rounds`` times out along DRIVE and back to where the robot stood: drive_order's per order."""
    tids = mqtt_tids(sim.proc.pid, (STATE_THREAD,) + MQTT_THREADS)
    out = []
    for r in range(rounds):
        for leg, points in (("out", DRIVE), ("back", tuple(reversed(DRIVE[:-1])) + ((0.0, 0.0),))):
            here = where(fleet.state(lambda s: "agvPosition" in s))
            out.append(drive_order(sim, fleet, home, tids, "d{}{}".format(leg, r),
                                   [here] + [offset(origin, dx, dy) for dx, dy in points]))
            time.sleep(1.0)
    return out


# printing ------------------------------------------------------------------------------------------

def print_latency(trips, spacing):
    print("| order → goal at move_base (canceled, then {:.1f} s, in turns) | n | p50 ms | p90 ms | p99 ms | max ms |"
          .format(spacing))
    print("|---|---:|---:|---:|---:|---:|")
    rows = [(label, trips[way][0]) for way, label in WAYS] + [
        ("(VDA 5050: the state saying it is taken, at the fleet client)", trips["vda"][1]),
        ("(HTTP: its answer)", trips["http"][1])]
    for label, t in rows:
        print("| {} | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} |".format(
            label, len(t), percentile(t, 50), percentile(t, 90), percentile(t, 99), max(t)))


def _mean_window(windows):
    shares = [statistics.mean(w[0][k] for w in windows) for k in range(len(windows[0][0]))]
    threads = [{name: statistics.mean(w[1][j].get(name, 0.0) for w in windows) for name in windows[0][1][j]}
               for j in range(2)]
    rates = {kind: statistics.mean(w[2].get(kind, 0.0) for w in windows) for kind in VDA_OUT}
    return shares, threads, rates


def print_cpu(windows, seconds):
    print("| at rest, CPU over {:.0f} s (% of one core) | VDA on | VDA off | VDA off, a second server | on − off "
          "| off − off (identical) | thread vda5050-state | MQTT threads, VDA on | MQTT threads, VDA off | mosquitto "
          "| VDA messages/s (state, visualization) |".format(seconds))
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    rows = [("window {}".format(i + 1), w) for i, w in enumerate(windows)]
    if len(windows) > 1:
        rows.append(("mean", _mean_window(windows)))
    for label, (shares, threads, rates) in rows:
        on, off, off2, broker = shares
        state = threads[0].get(STATE_THREAD)
        print("| {} | {:.2f} | {:.2f} | {:.2f} | {:+.2f} | {:+.2f} | {} | {} | {} | {:.2f} | {:.2f}, {:.2f} |".format(
            label, on, off, off2, on - off, off2 - off, "–" if state is None else "{:.3f}".format(state),
            _sum(threads[0], exclude=STATE_THREAD), _sum(threads[1]), broker, rates.get("state", 0.0),
            rates.get("visualization", 0.0)))


def _sum(threads, exclude=None):
    return "{:.3f}".format(sum(v for name, v in threads.items() if name != exclude)) if threads else "–"


def print_drives(results):
    print("| driving an order, 3.1 m over two nodes | s | state msg/s | state B/s | visualization msg/s "
          "| visualization B/s | Home Assistant's topics msg/s | B/s | server CPU | thread vda5050-state |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for i, (passed, vda, ha, cpu, threads) in enumerate(results):
        state, vis = vda.get("state", (0, 0)), vda.get("visualization", (0, 0))
        ha_n, ha_b = sum(n for n, _ in ha.values()), sum(b for _, b in ha.values())
        state_cpu = threads.get(STATE_THREAD)
        print("| {} | {:.1f} | {:.2f} | {:.0f} | {:.2f} | {:.0f} | {:.2f} | {:.0f} | {:.1f} % | {} |".format(
            ("out", "back")[i % 2], passed, state[0] / passed, state[1] / passed, vis[0] / passed, vis[1] / passed,
            ha_n / passed, ha_b / passed, cpu, "–" if state_cpu is None else "{:.3f} %".format(state_cpu)))


# the run -------------------------------------------------------------------------------------------

def on_the_robot(broker, home, folder, opts, skip):
    """Parts 1 and 3 on one VDA 5050 server: (latency, drives, schema problems of what the robot sent)."""
    sim = Sim(folder / "sim", broker, "bench-robot", VDA_ON)
    fleet = fleet_client(broker, "bench-robot")
    watch = None
    try:
        origin = where(fleet.ask_state(lambda s: "agvPosition" in s, message="a state with a position"))
        origin = dict(origin, x=round(origin["x"], 1), y=round(origin["y"], 1))
        watch = GoalWatch(sim.master_uri)
        latency = driven = None
        if "latency" not in skip:
            order_latency(sim, fleet, watch, origin, 3, opts.spacing, tag="warm")
            latency = order_latency(sim, fleet, watch, origin, opts.orders, opts.spacing)
        if "drive" not in skip:
            driven = drives(sim, fleet, home, origin, opts.drives)
        return latency, driven, fleet.unchecked_problems()
    finally:
        if watch is not None:
            watch.close()
        fleet.close()
        stop_process(sim.proc)


def at_rest(broker, home, folder, opts):
    servers = []
    try:
        servers.append(Sim(folder / "vda", broker, "vda", VDA_ON))
        servers += [Sim(folder / "ha", broker, "ha"), Sim(folder / "ha2", broker, "ha2")]
        wait_for(lambda: home.last(vda_base("vda") + "state"), timeout=20, message="the VDA server's state")
        time.sleep(opts.settle)
        return idle_cpu(servers, broker, home, opts.cpu_seconds, opts.cpu_repeat)
    finally:
        for sim in reversed(servers):
            stop_process(sim.proc)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--orders", type=int, default=50, help="orders (and POST /goto) measured")
    parser.add_argument("--spacing", type=float, default=0.3, help="s between the robot standing and the next")
    parser.add_argument("--settle", type=float, default=10.0, help="s after start-up before measuring CPU")
    parser.add_argument("--cpu-seconds", type=float, default=30.0, help="length of one CPU window")
    parser.add_argument("--cpu-repeat", type=int, default=2, help="CPU windows")
    parser.add_argument("--drives", type=int, default=1, help="orders driven out and back")
    parser.add_argument("--skip", default="", help="parts not to run, e.g. 'cpu' or 'latency,drive'")
    opts = parser.parse_args(argv)
    skip = set(filter(None, opts.skip.split(",")))

    folder = pathlib.Path(tempfile.mkdtemp(prefix="bench-vda-"))
    broker = Broker(folder)
    home = home_client(broker)
    latency = driven = cpu = None
    problems = []
    try:
        if not {"latency", "drive"} <= skip:
            latency, driven, problems = on_the_robot(broker, home, folder, opts, skip)
        if "cpu" not in skip:
            cpu = at_rest(broker, home, folder, opts)
    finally:
        home.close()
        broker.stop()
        shutil.rmtree(str(folder), ignore_errors=True)
    report(opts, latency, cpu, driven, problems)


def report(opts, latency, cpu, driven, problems):
    print("`flask-move-server --sim`, speed factor 1, mosquitto {}; load average {:.1f} {:.1f} {:.1f}\n".format(
        _mosquitto_version(), *os.getloadavg()))
    if latency:
        print_latency(latency, opts.spacing)
        print()
    if cpu:
        print_cpu(cpu, opts.cpu_seconds)
        print()
    if driven:
        print_drives(driven)
        print()
    if latency or driven:
        print("VDA 5050 messages the robot sent that break the standard's schemas: {}{}".format(
            len(problems), "".join("\n- " + p for p in problems[:10])))


if __name__ == "__main__":
    main()
