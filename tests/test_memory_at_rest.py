"""The server's memory at rest (issue 32): a configuration does not load what it does not use.

numpy (~14 MB of RSS, through genpy), paho (MQTT), jsonschema and zeroconf (mDNS) are loaded only
by the parts that use them; each check runs in a fresh process, built as ``flask-move-server`` builds
itself. docs/performance.md, "Memory at rest", has the RSS this keeps.
"""

import json
import os
import subprocess
import sys

import pytest

from tests.conftest import ROOT, free_port

HEAVY = ("numpy", "paho", "jsonschema", "zeroconf")

SERVER = """
import json, sys
from flask_move_server.app import cli, server_options
from flask_move_server.app.launching import split_ros_args

ours, ros_args = split_ros_args(sys.argv[1:])
server = cli.Server(server_options.load_config(server_options.parse_args(ours), ros_args)).start()
loaded = [name for name in {heavy!r} if name in sys.modules]
print(json.dumps({{"loaded": loaded, "port": server.port}}), flush=True)
server.close()
"""

GENPY = """
import json, sys
import flask_move_server
import genpy.message
from genpy.message import SerializationError, check_type

before = "numpy" in sys.modules
import numpy

check_type("x", "float64", numpy.float32(0.5))
try:
    check_type("x", "float64", "half a metre")
    refused = False
except SerializationError:
    refused = True
print(json.dumps({"numpy_with_genpy": before, "refused": refused}), flush=True)
"""


def run(tmp_path, program, *args):
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:{}".format(free_port()), ROS_HOME=str(tmp_path),
               ROS_IP="127.0.0.1", PYTHONPATH=ROOT)
    done = subprocess.run([sys.executable, "-c", program, *args], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_the_server_with_no_motors_and_no_mqtt_loads_no_numpy_paho_jsonschema_or_zeroconf(tmp_path):
    result = run(tmp_path, SERVER.format(heavy=HEAVY), "--host", "127.0.0.1", "--port", "0", "--no-mdns",
                 "--motor-backend", "none", "--waypoints", str(tmp_path / "waypoints.yaml"))
    assert result["port"] > 0  # it served
    assert result["loaded"] == []


def test_ros_messages_load_without_numpy_and_accept_numpy_floats_once_it_is_loaded(tmp_path):
    result = run(tmp_path, GENPY)
    assert result == {"numpy_with_genpy": False, "refused": True}


@pytest.mark.parametrize("module", ["flask_move_server.drive.messages", "flask_move_server.sim.world",
                                    "flask_move_server.ros.navigator"])
def test_whichever_of_the_servers_modules_imports_rospy_first_numpy_stays_unloaded(tmp_path, module):
    program = "import json, sys, {}; print(json.dumps(['rospy' in sys.modules, 'numpy' in sys.modules]))"
    assert run(tmp_path, program.format(module)) == [True, False]
