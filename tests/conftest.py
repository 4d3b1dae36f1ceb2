"""Shared fixtures: a real ROS master, the process's rospy node, real servers on port 0."""

import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time

import pytest

from tests import overload

# The real robot assembled on this process's rospy node: robot_config, robot, ready_robot,
# move_base (scripted actionlib stand-in), store, app, client.
pytest_plugins = ["tests.robot_fixtures"]

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


# Modules that drive a simulated robot, a browser or a roslaunch stack in real time. Under
# `make test`'s two pytest-xdist workers (Makefile XDIST: `-n 2 --dist loadscope`) the browser's
# modules (and the sim's explorations) run one after the other in one lane and the other real-time
# modules in another, so at most two of them share the two cores at a time; every other module is a
# unit of its own, whole on one worker (its module fixtures' state intact), each worker taking the
# next as it frees up. (xdist's own `loadgroup` marks are not honoured with pytest 9: a module's
# tests were spread over both workers and lost their shared state.)
REALTIME = ("sim", "modes_robot", "stack_launched", "launch", "motion_stop", "stop_path",
            "phantom_goals", "mdns_lan", "server_process", "estop", "home_assistant", "mqtt_resilience",
            "vda5050")


def lane_of(path):
    """The unit of work a test file belongs to under xdist: ``browser``, ``realtime``, or the file itself."""
    module = os.path.basename(path)[len("test_"):-len(".py")]
    if module.startswith("page") or module == "explore_sim":  # the explorations: the lanes' time evened out
        return "browser"
    if any(part in module for part in REALTIME):
        return "realtime"
    return path


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config, log):
    """``--dist loadscope`` with the lanes above as its scopes."""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    class Lanes(LoadScopeScheduling):
        def _split_scope(self, nodeid):
            return lane_of(nodeid.split("::", 1)[0])

    return Lanes(config, log)


def pytest_collection_modifyitems(config, items):
    """On a machine overloaded when the run starts, each test's time limit (pytest-timeout) grows with the load."""
    scale = overload.time_scale()
    if scale <= 1.0 or not config.pluginmanager.hasplugin("timeout"):
        return
    default = float(config.getini("timeout") or 0)
    for item in items:
        own = item.get_closest_marker("timeout")
        limit = own.args[0] if own is not None and own.args else default
        if limit:
            item.add_marker(pytest.mark.timeout(limit * scale), append=False)  # the closest: it wins


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """A failure on a loaded machine says so: the load, and what the sim servers' worlds logged of it."""
    outcome = yield
    report = outcome.get_result()
    if report.failed:
        why = overload.note()
        if why:
            report.sections.append(("machine overloaded?", why))


def pytest_report_header(config):
    import flask
    import waitress
    import yaml

    lines = ["python {} at {}".format(sys.version.split()[0], sys.executable)]
    for mod in (flask, waitress, yaml):
        lines.append("{} {} from {}".format(mod.__name__, _dist_version(mod.__name__), os.path.dirname(mod.__file__)))
    return lines


def _dist_version(name):
    """The installed version of a module's distribution (Flask 3 deprecates ``flask.__version__``)."""
    try:
        from importlib.metadata import version

        return version({"yaml": "PyYAML", "flask": "Flask"}.get(name, name))
    except Exception:
        return "?"


def default_sigint():
    """A child's ``preexec_fn``: SIGINT at its default, whatever this pytest process inherited.

    A shell starts background jobs (``nohup make test &``) with SIGINT ignored, some CIs start their
    steps so, and children inherit it: a Python child would then never see the Ctrl-C a test sends.
    """
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.fixture
def sigint_at_default():
    """Python's own Ctrl-C handler for this test (KeyboardInterrupt), even when pytest started ignoring SIGINT."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


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


@pytest.fixture(scope="module")
def browser():
    """One headless chromium for a browser-test module (tests/page_browser.py; Playwright imported only here)."""
    from tests.page_browser import Browser

    b = Browser()
    yield b
    b.close()


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

    server = waitress.create_server(app, host=host, port=0, threads=4, clear_untrusted_proxy_headers=True)
    thread = threading.Thread(target=server.run, name="test-waitress", daemon=True)
    thread.start()
    try:
        yield "http://{}:{}".format(host, server.effective_port)
    finally:
        stop_waitress(server)
        thread.join(5)


def stop_waitress(server):
    """Stop a waitress server running in another thread: close every channel from inside its loop."""
    from waitress import wasyncore

    try:
        server.trigger.pull_trigger(lambda: wasyncore.close_all(server._map))
    except OSError:
        pass  # the trigger is closed: the loop has ended already
    server.task_dispatcher.shutdown()


class ServerProcess:
    """``flask-move-server ARGS`` in a child process, its stderr collected as it comes; ``headers`` (a class
    or instance attribute set before starting it) go with each get and post (a token)."""

    headers = {}

    def __init__(self, *args, env=None, start_timeout=30, cwd=ROOT):
        self.proc = run_cli(*args, env=env, cwd=cwd)  # cwd: the checkout whose server runs (python -m reads it first)
        self.lines = []
        overload.SERVERS.add(self)  # a failure reads the world's "machine overloaded" lines
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        match = wait_for(lambda: self.find(r"serving the API on (http://\S+)") or self.proc.poll() is not None,
                         timeout=start_timeout, message="the server to log its URL")
        if match is True:
            raise AssertionError("the server exited {}:\n{}".format(self.proc.returncode, "".join(self.lines)))
        self.url = match.group(1)

    def _read(self):
        for line in self.proc.stderr:
            self.lines.append(line)

    def find(self, pattern):
        """The first match of ``pattern`` in the server's log so far, or None."""
        import re

        for line in list(self.lines):
            m = re.search(pattern, line)
            if m:
                return m
        return None

    def get(self, path, timeout=10):
        import requests

        return requests.get(self.url + path, timeout=timeout, headers=self.headers)

    def post(self, path, body=None, timeout=10):
        import requests

        return requests.post(self.url + path, json=body, timeout=timeout, headers=self.headers)

    def put(self, path, body=None, timeout=10):
        import requests

        return requests.put(self.url + path, json=body, timeout=timeout, headers=self.headers)

    def patch(self, path, body=None, timeout=10):
        import requests

        return requests.patch(self.url + path, json=body, timeout=timeout, headers=self.headers)

    def delete(self, path, timeout=10):
        import requests

        return requests.delete(self.url + path, timeout=timeout, headers=self.headers)

    def stop(self, sig=None, timeout=10):
        """Send ``sig`` (SIGTERM) and return the exit status."""
        import signal

        self.proc.send_signal(sig or signal.SIGTERM)
        code = self.proc.wait(timeout)
        self._reader.join(5)
        return code

    def kill(self):
        stop_process(self.proc)


def run_cli(*args, env=None, **kw):
    """Start ``flask-move-server`` as a real process (python -m, so no install is assumed)."""
    full_env = dict(os.environ)
    full_env.update(env or {})
    full_env.setdefault("PYTHONUNBUFFERED", "1")
    return subprocess.Popen(
        [sys.executable, "-m", "flask_move_server", *args],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=full_env, cwd=kw.pop("cwd", ROOT), text=True,
        preexec_fn=default_sigint, **kw
    )


# The product's threads; the tests' own servers (waitress in serve()) are the tests' business.
_OUR_THREAD_MODULES = ("flask_move_server", "zeroconf")


def _thread_module(thread):
    target = getattr(thread, "_target", None)
    if target is not None:
        return getattr(target, "__module__", "") or ""
    return type(thread).__module__


# What a server run in the checkout with the default config would write there (waypoints.file is
# waypoints.yaml, relative): a test must write only into its temporary folders.
CHECKOUT_LEFTOVERS = ("mode.json", "waypoints.yaml", "maps", os.path.join("config", "mode.json"),
                      os.path.join("config", "waypoints.yaml"))


@pytest.fixture(autouse=True)
def nothing_written_into_the_checkout():
    """Fail a test that leaves server state (mode.json, waypoints, maps) in the checkout itself."""
    before = {name for name in CHECKOUT_LEFTOVERS if os.path.lexists(os.path.join(ROOT, name))}
    yield
    after = {name for name in CHECKOUT_LEFTOVERS if os.path.lexists(os.path.join(ROOT, name))}
    assert after <= before, "the test wrote {} into the checkout {}".format(sorted(after - before), ROOT)


@pytest.fixture(autouse=True)
def no_thread_left_running():
    """Fail a test that leaves a thread of ours running: every part closes what it starts.

    Threads of session- or module-scoped fixtures exist before the test starts and are not counted;
    rospy's own connection threads are not ours and not checked.
    """
    before = set(threading.enumerate())
    yield

    def leftover():
        return [t for t in threading.enumerate()
                if t not in before and t.is_alive() and _thread_module(t).startswith(_OUR_THREAD_MODULES)]

    deadline = time.monotonic() + 3.0
    while leftover() and time.monotonic() < deadline:
        time.sleep(0.05)
    left = leftover()
    assert not left, "threads left running: {}".format(
        ", ".join("{} ({})".format(t.name, _thread_module(t)) for t in left))


@contextlib.contextmanager
def hardened(app, server_config, loop_timeout=None):
    """``app`` on the server the product runs, in a thread; yields (server, base URL).

    ``loop_timeout``: how long waitress's loop may sleep when nothing wakes it (it wakes once a
    second by itself), for tests that must see a write sent when it is made, not when the loop wakes.
    """
    from flask_move_server.http.server import HttpServer

    server = HttpServer(app, server_config)
    if loop_timeout is not None:
        server.adj.asyncore_loop_timeout = loop_timeout
    thread = threading.Thread(target=server.run, name="test-http-server", daemon=True)
    thread.start()
    try:
        yield server, "http://127.0.0.1:{}".format(server.effective_port)
    finally:
        server.stop()
        thread.join(5)
        server.close()


class SimReads:
    """What tests read of a ``--sim`` server (a ServerProcess with a ``waypoints`` file path)."""

    def status(self):
        return self.get("/status").json()

    def pose(self):
        return self.status()["pose"]

    def waypoint(self, name):
        import yaml

        return yaml.safe_load(self.waypoints.read_text())["waypoints"][name]
