"""Home Assistant over MQTT (issue 25): a command's way to move_base, the cost at rest, /stop in a flood.

    .venv/bin/python bench/bench_mqtt.py [--commands 100] [--spacing 0.2] [--settle 10]
        [--cpu-seconds 30] [--cpu-repeat 2] [--floods 5] [--flood 1000] [--stop-every 0.02]
        [--skip latency,cpu,flood]

A real broker (Debian's mosquitto on a free port, ``tests/mqtt_broker.py``) and real
``flask-move-server --sim`` processes (speed factor 1, the demo waypoints, each its own ROS master),
with Home Assistant's side played by a paho client here subscribed to ``#`` (as its MQTT
integration is) that publishes commands as it does (QoS 0, not retained).

1. **A command to its goal at move_base**: ``<root>/goto/set`` with a waypoint's name, published
   by that client, until the goal arrives on the sim's ``/move_base/goal`` (the sim's move_base is
   a real actionlib server), seen by a rospy subscriber in this process on the server's master
   (its own hop, the same for every row). The same from a second such client whose socket has
   ``TCP_NODELAY`` (paho leaves Nagle's algorithm on: a command sent while the client's last PUBACK
   is unacknowledged waits for the broker's delayed ACK, up to 40 ms), and with ``POST /goto
   {"name"}`` on one keep-alive connection for reference. ``--commands`` each, ``--spacing`` s
   apart, two of a way then two of the next in turns, the waypoint alternating so each is a new
   goal (it preempts the last).
2. **CPU at rest**: three servers side by side over the same windows (the machine's load falls on
   all alike), the same config but ``mqtt.enabled``: one connected to the broker, Home Assistant's
   discovery on, the client here subscribed to ``#``; two with MQTT off, the second to show how far
   two identical servers differ. User + system CPU from ``/proc/<pid>/stat`` over
   ``--cpu-seconds``, ``--cpu-repeat`` windows after ``--settle`` s, mosquitto's too, and the
   messages the robot published meanwhile. Two identical ``--sim`` servers differ by up to ~0.7 %
   of a core, which persists from window to window (the sim's own threads), more than the 0.2 %
   looked for; so, with py-spy installed (``pip install py-spy``), the MQTT threads' own CPU too:
   named by ``py-spy dump``, timed in ns from ``/proc/<pid>/task/<tid>/schedstat``.
3. **/stop in a command flood**: ``--flood`` goto commands in ``--flood-seconds`` over MQTT (the
   waypoint alternating) while a process of its own POSTs ``/stop`` every ``--stop-every`` s on one
   keep-alive connection; against the same with no flood, and with a flood of commands the server
   refuses (an unknown place: MQTT's own cost, no goal), ``--floods`` rounds of each in turns. Also
   how many commands the server dropped (at most 16 wait), how many goals reached move_base, and
   the server's CPU over the round.

Prints markdown tables (docs/performance.md, section "Home Assistant over MQTT").
"""

import argparse
import http.client
import json
import os
import pathlib
import re
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from tests.conftest import ServerProcess, free_port, stop_process, wait_for  # noqa: E402
from tests.mqtt_broker import Broker, Listener  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_sim import cpu_seconds  # noqa: E402  (a process's CPU from /proc, as bench_sim reads it)

ROOT_TOPIC = "flask-move-server/bench-robot"  # a name of its own: a robot left at "robot" names itself
GOTO = ROOT_TOPIC + "/goto/set"
PLACES = ("kitchen", "office")  # config/waypoints.demo.yaml: far apart, so every goal is a new one
LEAD = 0.5  # s for the stopper's process to start before its first /stop
MQTT_THREADS = ("paho-mqtt-client", "mqtt-sender", "mqtt-commands", "mqtt-state", "mqtt-discovery")


def percentile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q / 100.0 * (len(values) - 1))))]


# the processes -------------------------------------------------------------------------------

class NodelayBroker(Broker):
    """The tests' mosquitto, with ``set_tcp_nodelay true`` when ``nodelay`` (Nagle off on its sockets)."""

    def __init__(self, folder, nodelay):
        self.nodelay = nodelay
        super().__init__(folder)

    def start(self):
        if self.nodelay and "set_tcp_nodelay" not in self.conf.read_text():
            with self.conf.open("a") as f:
                f.write("set_tcp_nodelay true\n")
        return super().start()


class Sim(ServerProcess):
    """``flask-move-server --sim`` (speed factor 1, its own ROS master), MQTT on ``broker`` or off.

    ``name``: the robot's (``mdns.hostname``: its MQTT topics and client id, so several servers can
    share a broker); ``extra``: more lines of the ``mqtt:`` section (indented two spaces); ``root``: the
    checkout whose server runs; ``master_uri``: a master already running (else the sim starts its own);
    ``env``: more of the server's environment (``PYTHONPATH`` is put after ``root``)."""

    def __init__(self, home, broker=None, name="bench-robot", extra="", root=ROOT, master_uri=None, env=None):
        home.mkdir(parents=True, exist_ok=True)
        waypoints = home / "waypoints.yaml"
        shutil.copy(os.path.join(ROOT, "config", "waypoints.demo.yaml"), str(waypoints))
        config = home / "sim.yaml"
        config.write_text("mdns:\n  hostname: {}\nmqtt:\n  enabled: {}\n  host: 127.0.0.1\n  port: {}\n{}".format(
            name, "true" if broker else "false", broker.port if broker else 1883, extra))
        self.master_uri = master_uri or "http://127.0.0.1:{}".format(free_port())
        more = dict(env or {})
        path = os.pathsep.join(p for p in (root, more.pop("PYTHONPATH", "")) if p)
        env = dict(more, ROS_MASTER_URI=self.master_uri, ROS_HOME=str(home), ROS_LOG_DIR=str(home / "log"),
                   ROS_IP="127.0.0.1", PYTHONPATH=path)
        super().__init__("--sim", "--config", str(config), "--port", "0", "--no-mdns", "--waypoints", str(waypoints),
                         env=env, start_timeout=60, cwd=root)
        host, port = self.url.rsplit("/", 1)[1].split(":")
        self.conn = http.client.HTTPConnection(host, int(port), timeout=10)
        wait_for(lambda: self.get("/health").json().get("move_base") == "ready", timeout=60, message="move_base")
        if broker:
            wait_for(lambda: self.get("/status").json()["mqtt"]["state"] == "connected", timeout=20,
                     message="the server connected to the broker")
        self.places = {wp["name"]: wp for wp in self.get("/waypoints").json()["waypoints"]}

    def post_fast(self, path, body=None, conn=None):
        """POST on a keep-alive connection (``requests`` costs ~1 ms of its own): (status, JSON)."""
        conn = conn or self.conn
        conn.request("POST", path, body=json.dumps(body) if body is not None else None,
                     headers={"Content-Type": "application/json"})
        response = conn.getresponse()
        return response.status, json.loads(response.read() or b"null")

    def mqtt_status(self):
        return self.get("/status").json().get("mqtt") or {}


class GoalWatch:
    """A rospy subscriber on the server's ``/move_base/goal``: when each goal arrived, and where to."""

    def __init__(self, master_uri):
        os.environ.update(ROS_MASTER_URI=master_uri, ROS_IP="127.0.0.1")
        import rospy
        from move_base_msgs.msg import MoveBaseActionGoal

        self._rospy = rospy
        self._cond = threading.Condition()
        self.arrivals = []  # (monotonic time, x)
        rospy.init_node("bench_mqtt", anonymous=True, disable_signals=True)
        self._sub = rospy.Subscriber("/move_base/goal", MoveBaseActionGoal, self._arrived, queue_size=2000,
                                     tcp_nodelay=True)
        wait_for(lambda: self._sub.get_num_connections() > 0, timeout=20, message="the /move_base/goal subscription")

    def _arrived(self, msg):
        now = time.monotonic()
        with self._cond:
            self.arrivals.append((now, msg.goal.target_pose.pose.position.x))
            self._cond.notify_all()

    def arrival(self, x, after, timeout=10.0):
        """The first arrival of a goal to ``x`` at or after ``after``."""
        def found():
            return next((t for t, gx in reversed(self.arrivals) if t >= after and abs(gx - x) < 1e-6), None)

        with self._cond:
            if not self._cond.wait_for(lambda: found() is not None, timeout):
                raise RuntimeError("no goal to x={} reached move_base".format(x))
            return found()

    def count_since(self, t):
        with self._cond:
            return sum(1 for a, _ in self.arrivals if a >= t)

    def close(self):
        self._sub.unregister()
        self._rospy.signal_shutdown("bench done")


# 1. a command to move_base ---------------------------------------------------------------------

WAYS = (("mqtt", "MQTT `goto/set`: paho → mosquitto → server"),
        ("mqtt_nodelay", "MQTT `goto/set`, the sending client's socket with TCP_NODELAY"),
        ("http", "HTTP `POST /goto {name}`"))


def command_latency(sim, clients, watch, commands, spacing):
    """ms from the command sent to its goal at move_base, per way (WAYS), and HTTP's answer ms.

    ``clients``: the paho client sending for each MQTT way. Two commands of a way, then two of the
    next, the place alternating at every command."""
    trips = {way: [] for way, _ in WAYS}
    answers = []
    for i in range(len(WAYS) * commands):
        way = WAYS[(i // 2) % len(WAYS)][0]
        place = PLACES[i % 2]
        x = sim.places[place]["x"]
        started = time.monotonic()
        if way == "http":
            status, body = sim.post_fast("/goto", {"name": place})
            answers.append((time.monotonic() - started) * 1e3)
            if status not in (200, 202):
                raise RuntimeError("POST /goto answered {}: {}".format(status, body))
        else:
            clients[way].client.publish(GOTO, place, qos=0)
        trips[way].append((watch.arrival(x, started) - started) * 1e3)
        time.sleep(spacing)
    sim.post_fast("/stop")
    return trips, answers


def nodelay_listener(broker):
    """Another Home Assistant (subscribed to everything, QoS 1), its socket with Nagle's algorithm off."""
    listener = Listener(broker)
    listener.client.socket().setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    return listener


# 2. CPU at rest ----------------------------------------------------------------------------------

def thread_cpu(pid):
    """{tid: CPU seconds} of every thread of ``pid``: the scheduler's nanoseconds on a CPU (schedstat),
    not utime + stime's 10 ms ticks, which over 30 s cannot tell 0.03 % from nothing."""
    out = {}
    for tid in os.listdir("/proc/{}/task".format(pid)):
        try:
            with open("/proc/{}/task/{}/schedstat".format(pid, tid)) as f:
                out[int(tid)] = int(f.read().split()[0]) / 1e9
        except (OSError, ValueError, IndexError):
            continue
    return out


def mqtt_tids(pid, prefixes=MQTT_THREADS):
    """The OS thread ids of the server's threads named ``prefixes`` (its MQTT threads), named by
    ``py-spy dump``; {} without py-spy."""
    spy = shutil.which("py-spy") or os.path.join(os.path.dirname(sys.executable), "py-spy")
    if not os.path.exists(spy):
        return {}
    try:
        dump = subprocess.run([spy, "dump", "--pid", str(pid)], capture_output=True, text=True, timeout=30).stdout
    except (OSError, subprocess.SubprocessError):
        return {}
    tids = {}
    for m in re.finditer(r'^Thread (0x[0-9A-Fa-f]+|\d+) \([^)]*\): "([^"]+)"', dump, re.M):
        name = m.group(2)
        if name.startswith(prefixes):
            ident = m.group(1)
            tids[int(ident, 16) if ident.startswith("0x") else int(ident)] = name
    return tids


def published(home):
    """Messages the listener got from the robot (its state, availability, discovery) so far."""
    with home._lock:
        return sum(1 for m in home.messages if m[1].startswith((ROOT_TOPIC + "/", "homeassistant/")))


def idle_cpu(servers, broker, home, seconds, repeat):
    """Per window: each server's CPU and mosquitto's (% of one core), the MQTT-on server's (the
    first) MQTT threads' ({name: %}, empty without py-spy), and the messages it published per s."""
    tids = mqtt_tids(servers[0].proc.pid)
    windows = []
    for _ in range(repeat):
        procs = [s.proc.pid for s in servers] + [broker.proc.pid]
        before = [cpu_seconds(p) for p in procs]
        threads0 = thread_cpu(servers[0].proc.pid)
        published0 = published(home)
        started = time.monotonic()
        time.sleep(seconds)
        passed = time.monotonic() - started
        shares = [100.0 * (cpu_seconds(p) - b) / passed for p, b in zip(procs, before)]
        threads1 = thread_cpu(servers[0].proc.pid)
        mqtt = {name: 100.0 * (threads1.get(tid, 0.0) - threads0[tid]) / passed
                for tid, name in tids.items() if tid in threads0}
        windows.append((shares, mqtt, (published(home) - published0) / passed))
    return windows


# 3. /stop in a flood ----------------------------------------------------------------------------

STOPPER = """
import http.client, json, sys, time
host, port = sys.argv[1], int(sys.argv[2])
every, start, until = (float(a) for a in sys.argv[3:6])
conn = http.client.HTTPConnection(host, port, timeout=10)
conn.connect()
out, tick = [], start
while tick < until:
    time.sleep(max(0.0, tick - time.monotonic()))
    started = time.monotonic()
    conn.request("POST", "/stop", headers={"Content-Type": "application/json"})
    response = conn.getresponse()
    canceled = bool(json.loads(response.read() or b"{}").get("canceled_goal"))
    out.append(((time.monotonic() - started) * 1e3, response.status, canceled))
    tick += every
print(json.dumps(out))
"""


class Stopper:
    """POST /stop every ``every`` s from ``start`` to ``until`` (``time.monotonic``, which every process
    shares) on one keep-alive connection, from a process of its own (a phone: nothing else of this
    bench's, the flood's publishing or the listener, competes with it for its interpreter)."""

    def __init__(self, sim, every, start, until):
        host, port = sim.url.rsplit("/", 1)[1].split(":")
        self.proc = subprocess.Popen([sys.executable, "-c", STOPPER, host, port, str(every), str(start), str(until)],
                                     stdout=subprocess.PIPE, text=True)
        self.times, self.canceled, self.failed = [], 0, 0

    def join(self):
        out, _ = self.proc.communicate(timeout=60)
        for ms, status, canceled in json.loads(out):
            self.times.append(ms)
            self.failed += status != 200
            self.canceled += canceled
        return self


def stop_round(sim, flooder, watch, places, count, seconds, every):
    """``seconds`` of ``count`` goto commands to ``places`` in turns (none: count 0) with the stopper
    running: (the stopper, commands the server dropped, goals that reached move_base, the server's CPU
    over those seconds in % of one core)."""
    dropped0 = sim.mqtt_status().get("dropped_in", 0)
    start = time.monotonic() + LEAD
    stopper = Stopper(sim, every, start, start + seconds)
    time.sleep(max(0.0, start - time.monotonic()))
    cpu0 = cpu_seconds(sim.proc.pid)
    batch = 10
    for i in range(0, count, batch):
        time.sleep(max(0.0, start + seconds * i / count - time.monotonic()))
        for j in range(i, min(count, i + batch)):
            flooder.client.publish(GOTO, places[j % len(places)], qos=0)
    time.sleep(max(0.0, start + seconds - time.monotonic()))
    cpu = 100.0 * (cpu_seconds(sim.proc.pid) - cpu0) / (time.monotonic() - start)
    stopper.join()
    time.sleep(1.0)  # the commands taken are acted on
    goals = watch.count_since(start)
    dropped = sim.mqtt_status().get("dropped_in", 0) - dropped0
    sim.post_fast("/stop")
    time.sleep(0.5)
    return stopper, dropped, goals, cpu


# printing ------------------------------------------------------------------------------------------

def print_latency(trips, answers, spacing):
    print("| command → goal at move_base ({:.1f} s apart, in turns) | n | p50 ms | p90 ms | p99 ms | max ms |".format(
        spacing))
    print("|---|---:|---:|---:|---:|---:|")
    rows = [(label, trips[way]) for way, label in WAYS] + [("(HTTP: its answer)", answers)]
    for label, t in rows:
        print("| {} | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} |".format(
            label, len(t), percentile(t, 50), percentile(t, 90), percentile(t, 99), max(t)))


def print_cpu(windows, seconds):
    print("| at rest, CPU over {:.0f} s (% of one core) | MQTT on | MQTT off | MQTT off, a second server | on − off "
          "| off − off (identical) | MQTT threads: mqtt-state | the other MQTT threads | mosquitto "
          "| messages/s published |".format(seconds))
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    rows = [("window {}".format(i + 1), w) for i, w in enumerate(windows)]
    if len(windows) > 1:
        mean = ([statistics.mean(w[0][k] for w in windows) for k in range(4)],
                {name: statistics.mean(w[1].get(name, 0.0) for w in windows) for name in windows[0][1]},
                statistics.mean(w[2] for w in windows))
        rows.append(("mean", mean))
    for label, (shares, mqtt, rate) in rows:
        on, off, off2, broker = shares
        state = mqtt.get("mqtt-state")
        others = sum(v for name, v in mqtt.items() if name != "mqtt-state")
        print("| {} | {:.2f} | {:.2f} | {:.2f} | {:+.2f} | {:+.2f} | {} | {} | {:.2f} | {:.2f} |".format(
            label, on, off, off2, on - off, off2 - off, "–" if state is None else "{:.3f}".format(state),
            "{:.3f}".format(others) if mqtt else "–", broker, rate))


def print_stops(rows, count, seconds, every):
    print("| POST /stop every {:.0f} ms, {:.0f} s a round | n | p50 ms | p90 ms | p99 ms | max ms | canceled a goal "
          "| not 200 | flood commands dropped | goals at move_base | server CPU |".format(every * 1e3, seconds))
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, results in rows:
        t = [ms for r in results for ms in r[0].times]
        flood = "no flood" not in label
        print("| {} ({} rounds) | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} | {} | {} | {} | {} | {:.0f} % |".format(
            label, len(results), len(t), percentile(t, 50), percentile(t, 90), percentile(t, 99), max(t),
            sum(r[0].canceled for r in results), sum(r[0].failed for r in results),
            "{} of {}".format(sum(r[1] for r in results), count * len(results)) if flood else "–",
            sum(r[2] for r in results), statistics.mean(r[3] for r in results)))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--commands", type=int, default=100, help="goto commands per way (MQTT, HTTP)")
    parser.add_argument("--spacing", type=float, default=0.2, help="s between two commands")
    parser.add_argument("--settle", type=float, default=10.0, help="s after start-up before measuring CPU")
    parser.add_argument("--cpu-seconds", type=float, default=30.0, help="length of one CPU window")
    parser.add_argument("--cpu-repeat", type=int, default=2, help="CPU windows")
    parser.add_argument("--floods", type=int, default=5, help="flood rounds (and as many without)")
    parser.add_argument("--flood", type=int, default=1000, help="goto commands per flood")
    parser.add_argument("--flood-seconds", type=float, default=1.0, help="length of one flood")
    parser.add_argument("--stop-every", type=float, default=0.02, help="s between two POST /stop")
    parser.add_argument("--broker-nodelay", action="store_true", help="mosquitto with set_tcp_nodelay true")
    parser.add_argument("--skip", default="", help="parts not to run, e.g. 'cpu' or 'latency,flood'")
    opts = parser.parse_args(argv)
    skip = set(filter(None, opts.skip.split(",")))

    home_dir = pathlib.Path(tempfile.mkdtemp(prefix="bench-mqtt-"))
    broker = NodelayBroker(home_dir, opts.broker_nodelay)
    home = Listener(broker)  # Home Assistant: subscribed to everything
    flooder = Listener(broker, topics=())  # a script gone wrong
    sims, watch = [], None
    latency = stops = cpu = None
    try:
        if not {"latency", "flood"} <= skip:
            sim = Sim(home_dir / "sim", broker)
            sims.append(sim)
            watch = GoalWatch(sim.master_uri)
            if "latency" not in skip:
                other = nodelay_listener(broker)
                try:
                    clients = {"mqtt": home, "mqtt_nodelay": other}
                    command_latency(sim, clients, watch, 5, opts.spacing)  # warm-up
                    latency = command_latency(sim, clients, watch, opts.commands, opts.spacing)
                finally:
                    other.close()
            if "flood" not in skip:
                kinds = (("no flood", (), 0),
                         ("{} goto/set in {:.0f} s over MQTT".format(opts.flood, opts.flood_seconds), PLACES,
                          opts.flood),
                         ("{} goto/set of an unknown place (each refused)".format(opts.flood), ("garage",),
                          opts.flood))
                stops = [(label, []) for label, _, _ in kinds]
                for _ in range(opts.floods):  # in turns, so the machine's drifting load falls on each alike
                    for (_label, places, count), (_, results) in zip(kinds, stops):
                        results.append(stop_round(sim, flooder, watch, places, count, opts.flood_seconds,
                                                  opts.stop_every))
            watch.close()
            watch = None
            stop_process(sims.pop().proc)
        if "cpu" not in skip:
            sims += [Sim(home_dir / "on", broker), Sim(home_dir / "off"), Sim(home_dir / "off2")]
            time.sleep(opts.settle)
            cpu = idle_cpu(sims, broker, home, opts.cpu_seconds, opts.cpu_repeat)
    finally:
        if watch is not None:
            watch.close()
        for sim in reversed(sims):
            stop_process(sim.proc)
        home.close()
        flooder.close()
        broker.stop()
        shutil.rmtree(str(home_dir), ignore_errors=True)

    print("`flask-move-server --sim`, speed factor 1, mosquitto {}; load average {:.1f} {:.1f} {:.1f}\n".format(
        _mosquitto_version(), *os.getloadavg()))
    if latency:
        print_latency(*latency, opts.spacing)
        print()
    if cpu:
        print_cpu(cpu, opts.cpu_seconds)
        print()
    if stops:
        print_stops(stops, opts.flood, opts.flood_seconds, opts.stop_every)


def _mosquitto_version():
    exe = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
    try:
        out = subprocess.run([exe, "-h"], capture_output=True, text=True, timeout=5).stdout
    except (OSError, subprocess.SubprocessError):
        return "?"
    m = re.search(r"version (\S+)", out)
    return m.group(1) if m else "?"


if __name__ == "__main__":
    main()
