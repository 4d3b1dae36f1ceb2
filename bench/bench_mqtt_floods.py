"""Hostile MQTT input (issue 34): ``/stop`` p99, the drive loop's worst gap and RSS under each flood.

    .venv/bin/python bench/bench_mqtt_floods.py [--window 6] [--compare DIR] [--only NAME,…]

A real broker (Debian's mosquitto on a free port) and, for each flood, a fresh ``flask-move-server
--sim`` (MQTT, Home Assistant's discovery and VDA 5050 on; one ROS master for all, so a rospy
subscriber here follows each server's ``/odom``). From a paho client here, over the first 2 s of a
``--window`` s window:

- ``instant-long``: 60 ``instantActions`` messages of ~254 KB (one action, its id and its type of
  127 KB each): the probe's, which made every state 17 MB;
- ``instant-limit``: 60 messages of 50 unknown actions whose id and type are at the length the
  factsheet allows (200 characters, 2-byte letters): the largest the robot takes and keeps;
- ``state-requests``: 10,000 ``stateRequest`` instant actions, one a message;
- ``goto-unknown``: 10,000 Home Assistant ``goto/set`` of a place that is not there;
- ``state-fake``: 10,000 messages on the robot's own ``state`` topic from another client (the robot
  listens there since issue 34, item 3, to notice someone speaking as it).

Over the whole window a process of its own POSTs ``/stop`` every 0.2 s (bench_mqtt's ``Stopper``),
the worst gap between two ``/odom`` messages is taken, and a paho client counts the bytes of
``state`` the robot published; the server's RSS before, its peak (VmHWM) and after. ``--compare
DIR`` measures another checkout's server the same way in the same run (``git worktree add DIR REV``).
Targets: ``/stop`` p99 <= 50 ms, gap <= 100 ms, RSS growth <= 5 MB. Prints a markdown table.
"""

import argparse
import json
import os
import pathlib
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, ROOT)
sys.path.insert(0, HERE)

from bench_drive_gaps import OdomGaps  # noqa: E402
from bench_mqtt import GOTO, Sim, Stopper, percentile  # noqa: E402

from tests.conftest import free_port, start_master, stop_process  # noqa: E402
from tests.mqtt_broker import Broker, Listener  # noqa: E402

VDA = "uagv/v2/flask-move-server/bench-robot/"
VDA_ON = "  vda5050:\n    enabled: true\n"
FLOOD_SECONDS = 2.0
STOP_EVERY = 0.2


def header(n):
    return {"headerId": n, "timestamp": "2026-12-01T12:00:00.000Z", "version": "2.0.0",
            "manufacturer": "flask-move-server", "serialNumber": "bench-robot"}


def instant(n, actions):
    return json.dumps(dict(header(n), actions=actions))


def long_ids(n):
    text = "x" * (127 * 1024)
    return instant(n, [{"actionId": "{}-{}".format(n, text), "actionType": text + str(n), "blockingType": "NONE"}])


def at_the_limit(n):
    return instant(n, [{"actionId": "é" * 190 + "{:05d}{:05d}".format(n, i), "actionType": "ü" * 200,
                        "blockingType": "NONE"} for i in range(50)])


def state_request(n):
    return instant(n, [{"actionId": "ask-{}".format(n), "actionType": "stateRequest", "blockingType": "NONE"}])


FLOODS = {  # name: (what the table says, the topic, the payload of message n, how many)
    "instant-long": ("60 instantActions of 254 KB (an id and a type of 127 KB)", VDA + "instantActions", long_ids, 60),
    "instant-limit": ("60 instantActions of 50 actions at the 200-character limit", VDA + "instantActions",
                      at_the_limit, 60),
    "state-requests": ("10,000 stateRequest instant actions", VDA + "instantActions", state_request, 10000),
    "goto-unknown": ("10,000 goto/set of an unknown place", GOTO, lambda n: "nowhere-{}".format(n), 10000),
    "state-fake": ("10,000 fake states on the robot's own state topic", GOTO.rsplit("/", 2)[0] + "/state",
                   lambda n: json.dumps({"status": "driving", "target": "front door", "n": n}), 10000),
}


class Bytes(Listener):
    """A paho client that counts the bytes on ``topic`` and keeps none of them."""

    def __init__(self, broker, topic):
        self.count, self.size = 0, 0
        super().__init__(broker, topics=(topic,))

    def _keep(self, client, userdata, message):
        self.count += 1
        self.size += len(message.payload)


def rss_mb(pid, field="VmRSS:"):
    with open("/proc/{}/status".format(pid)) as f:
        return next(int(line.split()[1]) for line in f if line.startswith(field)) / 1024.0


def flood(client, topic, payload, count):
    """``count`` messages over FLOOD_SECONDS, QoS 0, in batches of 10."""
    start = time.monotonic()
    for i in range(0, count, 10):
        time.sleep(max(0.0, start + FLOOD_SECONDS * i / count - time.monotonic()))
        for n in range(i, min(count, i + 10)):
            client.publish(topic, payload(n), qos=0)


def measure(sim, broker, gaps, name, window):
    """(stop p99 ms, stops not 200, worst gap ms, RSS before, peak, after, state MB) over one flood."""
    _label, topic, payload, count = FLOODS[name]
    states = Bytes(broker, VDA + "state")
    sender = Listener(broker, topics=())
    before = rss_mb(sim.proc.pid)
    start = time.monotonic() + 0.5
    stopper = Stopper(sim, STOP_EVERY, start, start + window)
    time.sleep(max(0.0, start - time.monotonic()))
    thread = threading.Thread(target=flood, args=(sender.client, topic, payload, count), daemon=True)
    thread.start()
    time.sleep(max(0.0, start + window - time.monotonic()))
    stopper.join()
    thread.join(30)
    worst, _ = gaps.worst(start)
    row = (percentile(stopper.times, 99), stopper.failed, worst, before, rss_mb(sim.proc.pid, "VmHWM:"),
           rss_mb(sim.proc.pid), states.size / 1e6)
    sender.close()
    states.close()
    return row


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--window", type=float, default=6.0, help="seconds measured for each flood (from its start)")
    parser.add_argument("--compare", metavar="DIR", action="append", default=[], help="another checkout's server")
    parser.add_argument("--only", default="", help="comma-separated floods (default all): " + ", ".join(FLOODS))
    opts = parser.parse_args(argv)
    names = [n for n in opts.only.split(",") if n] or list(FLOODS)
    folder = pathlib.Path(tempfile.mkdtemp(prefix="bench-mqtt-floods-"))
    broker = Broker(folder)
    port = free_port()
    master = start_master(port)
    os.environ.update(ROS_MASTER_URI="http://127.0.0.1:{}".format(port), ROS_IP="127.0.0.1")
    import rospy

    rospy.init_node("bench_mqtt_floods", anonymous=True, disable_signals=True)
    gaps, rows = OdomGaps(), []
    try:
        for root in [ROOT] + [os.path.abspath(d) for d in opts.compare]:
            for name in names:
                sim = Sim(folder / "{}-{}".format(len(rows), name), broker, extra=VDA_ON, root=root,
                          master_uri=os.environ["ROS_MASTER_URI"])
                try:
                    label = "this checkout" if root == ROOT else os.path.basename(root)
                    rows.append((label, FLOODS[name][0]) + measure(sim, broker, gaps, name, opts.window))
                finally:
                    stop_process(sim.proc)
    finally:
        stop_process(master)
        broker.stop()
    print("| server | flood (over 2 s) | POST /stop p99 ms | /stop not 200 | worst /odom gap ms | RSS before MB "
          "| peak RSS MB | RSS after MB | state sent MB |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for row in rows:
        print("| {} | {} | {:.1f} | {} | {:.0f} | {:.1f} | {:.1f} | {:.1f} | {:.1f} |".format(*row))


if __name__ == "__main__":
    main(sys.argv[1:])
