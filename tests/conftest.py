"""Shared fixtures: a real ROS master, the process's rospy node, real servers on port 0."""

import contextlib
import os
import shutil
import socket
import subprocess
import sys
import threading
import time

import pytest

# The real robot assembled on this process's rospy node: robot_config, robot, ready_robot,
# move_base (scripted actionlib stand-in), store, app, client.
pytest_plugins = ["tests.robot_fixtures"]

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def pytest_report_header(config):
    import flask
    import waitress
    import yaml

    lines = ["python {} at {}".format(sys.version.split()[0], sys.executable)]
    for mod in (flask, waitress, yaml):
        version = getattr(mod, "__version__", None) or _dist_version(mod.__name__)
        lines.append("{} {} from {}".format(mod.__name__, version, os.path.dirname(mod.__file__)))
    return lines


def _dist_version(name):
    try:
        from importlib.metadata import version

        return version({"yaml": "PyYAML", "flask": "Flask"}.get(name, name))
    except Exception:
        return "?"


def free_port():
    with contextlib.closing(socket.socket()) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_for(predicate, timeout=10.0, interval=0.02, message="condition"):
    """Poll ``predicate`` until true; fail the test after ``timeout`` seconds."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        value = predicate()
        if value:
            return value
        time.sleep(interval)
    raise AssertionError("timed out after {}s waiting for {}".format(timeout, message))


def start_master(port, env=None):
    """A real ``rosmaster --core`` on ``port``; returns the Popen."""
    proc = subprocess.Popen(
        [shutil.which("rosmaster") or "rosmaster", "--core", "-p", str(port)],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
    )
    from flask_move_server.ros import master

    uri = "http://127.0.0.1:{}".format(port)
    wait_for(lambda: master.identity("/test", uri, timeout=0.5), message="rosmaster on port {}".format(port))
    return proc


def stop_process(proc, timeout=5):
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@pytest.fixture(scope="session")
def ros_home(tmp_path_factory):
    home = tmp_path_factory.mktemp("ros_home")
    os.environ["ROS_HOME"] = str(home)
    os.environ["ROS_LOG_DIR"] = str(home / "log")
    return home


@pytest.fixture(scope="session")
def ros_master(ros_home):
    """A real ROS master for this test session; ROS_MASTER_URI points at it."""
    port = free_port()
    proc = start_master(port)
    uri = "http://127.0.0.1:{}".format(port)
    os.environ["ROS_MASTER_URI"] = uri
    os.environ["ROS_IP"] = "127.0.0.1"
    yield uri
    stop_process(proc)


@pytest.fixture(scope="session")
def ros_node(ros_master):
    """This test process's rospy node (rospy allows one per process), connected."""
    from flask_move_server.ros.node import RosNode

    node = RosNode("flask_move_server_tests", check_period=0.5)
    node.start()
    assert node.wait_connected(15), "rospy could not register with the test master"
    yield node
    node.close()


_names = iter(range(1, 1000000))


@pytest.fixture
def unique_name():
    """A fresh ROS name per test, so tests never hear each other's topics."""
    return "t{}".format(next(_names))


@contextlib.contextmanager
def serve(app, host="127.0.0.1"):
    """Serve a WSGI app with a real waitress server on a free port; yields its base URL."""
    import waitress

    server = waitress.create_server(app, host=host, port=0, threads=4)
    thread = threading.Thread(target=server.run, name="test-waitress", daemon=True)
    thread.start()
    try:
        yield "http://{}:{}".format(host, server.effective_port)
    finally:
        server.close()
        server.task_dispatcher.shutdown()
        thread.join(5)


def run_cli(*args, env=None, **kw):
    """Start ``flask-move-server`` as a real process (python -m, so no install is assumed)."""
    full_env = dict(os.environ)
    full_env.update(env or {})
    full_env.setdefault("PYTHONUNBUFFERED", "1")
    return subprocess.Popen(
        [sys.executable, "-m", "flask_move_server", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=full_env, cwd=kw.pop("cwd", ROOT), text=True, **kw
    )
