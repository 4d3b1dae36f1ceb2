"""Run an HTTP server with a timestamp at each stage of a goal's way; SIGUSR1 writes them out.

``python bench/stages.py OUT.json [--root DIR] -m flask_move_server --config …`` or ``… OUT.json bench/bare_server.py``;
``--root DIR``: the server's package from the checkout in DIR (``bench_goals.py --compare``), else from this one.
The stages, each taken where the server's own code (or waitress's, Flask's, rospy's) enters it:

- ``read``: waitress's event loop has bytes of the request (``HTTPChannel.received``, or our
  ``RobotChannel.received``, which parses without calling it)
- ``worker``: a worker thread starts the request (``WSGITask.service``)
- ``route``: Flask has matched it and run the ``before_request`` checks (``Flask.dispatch_request``)
- ``publish``: the goal message is handed to rospy (``Publisher.publish`` on a ``…/goal`` topic)
- ``socket``: its bytes start on their way to move_base (the connection's ``write_data``)

Each record is ``[stage, time.monotonic()]``: the bench's client and the move_base stand-in use the
same clock, so ``bench_goals.py --stages`` can take each goal's first record of each stage after
its request was sent. A wrapper costs about a microsecond; both servers carry the same ones.
"""

import json
import os
import runpy
import signal
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

STAGES = ("read", "worker", "route", "publish", "socket")
_records = []


def _timed(cls, name, stage, applies=None):
    original = getattr(cls, name)

    def timed(self, *args, **kwargs):
        if applies is None or applies(self):
            _records.append((stage, time.monotonic()))
        return original(self, *args, **kwargs)

    setattr(cls, name, timed)


def _to_goal_topic(connection):
    protocol = getattr(connection, "protocol", None)
    return getattr(protocol, "resolved_name", "").endswith("/goal")


def install():
    import flask
    import rospy.impl.tcpros_base
    import rospy.topics
    import waitress.channel
    import waitress.task

    _timed(waitress.channel.HTTPChannel, "received", "read")
    _timed(waitress.task.WSGITask, "service", "worker")
    _timed(flask.Flask, "dispatch_request", "route")
    _timed(rospy.topics.Publisher, "publish", "publish", lambda pub: pub.resolved_name.endswith("/goal"))
    _timed(rospy.impl.tcpros_base.TCPROSTransport, "write_data", "socket", _to_goal_topic)
    try:
        from flask_move_server.http.connection import RobotChannel
        from flask_move_server.ros.direct import DirectConnection
    except ImportError:  # the bare server's environment may lack them: nothing of ours to time there
        return
    if "received" in vars(RobotChannel):
        _timed(RobotChannel, "received", "read")
    _timed(DirectConnection, "write_data", "socket", _to_goal_topic)


def main():
    out, command = sys.argv[1], sys.argv[2:]
    root = ROOT
    if command[0] == "--root":
        root, command = os.path.abspath(command[1]), command[2:]
    sys.path.insert(0, root)
    install()
    signal.signal(signal.SIGUSR1, lambda *_: _write(out))
    if command[0] == "-m":
        sys.argv = command[1:]
        runpy.run_module(command[1], run_name="__main__", alter_sys=True)
    else:
        sys.argv = command
        runpy.run_path(command[0], run_name="__main__")


def _write(path):
    with open(path + ".part", "w") as f:
        json.dump(list(_records), f)
    os.replace(path + ".part", path)


if __name__ == "__main__":
    main()
