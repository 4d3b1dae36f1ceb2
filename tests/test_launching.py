"""The entry points' shared launch plumbing: ROS arguments, node names, private params from the master.

Private params are read from a real ROS master, and from a stand-in master over real XML-RPC that
answers slowly (a Pi still booting) or not at all.
"""

import ast
import contextlib
import pathlib
import threading
import time
import xmlrpc.server

import pytest

from flask_move_server import config
from flask_move_server.app import launching
from flask_move_server.core.errors import ConfigError
from tests.conftest import ServerProcess, free_port

PACKAGE = pathlib.Path(launching.__file__).parent.parent


def test_no_module_imports_the_server_wiring():
    importers = []
    for path in PACKAGE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + ["{}.{}".format(node.module, a.name) for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            if "flask_move_server.app.cli" in names:
                importers.append(str(path.relative_to(PACKAGE)))
    assert importers == ["__main__.py"]


def test_roslaunch_arguments_are_split_from_ours_and_name_the_node(monkeypatch):
    monkeypatch.delenv("ROS_NAMESPACE", raising=False)
    ours, ros = launching.split_ros_args(["--port", "0", "__name:=server", "__ns:=/robot1", "cmd_vel:=/x"])
    assert ours == ["--port", "0"] and ros == ["__name:=server", "__ns:=/robot1", "cmd_vel:=/x"]
    assert launching.ros_node_name(ros) == "/robot1/server"
    assert launching.ros_node_name(["cmd_vel:=/x"]) is None


class SlowMaster:
    """A ROS master's ``getParam`` over real XML-RPC that answers after ``delay`` seconds."""

    def __init__(self, params, delay):
        self.params, self.delay, self.asked = params, delay, []
        self.server = xmlrpc.server.SimpleXMLRPCServer(("127.0.0.1", 0), logRequests=False, allow_none=True)
        self.server.register_function(self.getParam, "getParam")
        self.uri = "http://127.0.0.1:{}".format(self.server.server_address[1])
        self._thread = threading.Thread(target=self.server.serve_forever, daemon=True)
        self._thread.start()

    def getParam(self, caller_id, key):  # noqa: N802 (the ROS master API's name)
        self.asked.append(key)
        time.sleep(self.delay)
        if key.rstrip("/") == caller_id:
            return [1, "", self.params]
        return [-1, "no such parameter", 0]

    def close(self):
        self.server.shutdown()
        self.server.server_close()
        self._thread.join(5)


@contextlib.contextmanager
def slow_master(params, delay):
    master = SlowMaster(params, delay)
    try:
        yield master
    finally:
        master.close()


def test_private_params_are_read_from_a_master_slower_than_two_seconds(monkeypatch, caplog):
    with slow_master({"server": {"port": 7123}, "drive": {"backend": "sim"}}, delay=2.5) as master:
        monkeypatch.setenv("ROS_MASTER_URI", master.uri)
        with caplog.at_level("WARNING", logger="flask_move_server"):
            loaded = launching.apply_private_params(config.Config(), "/robot/server", wait=10)
    assert loaded.server.port == 7123 and loaded.drive.backend == "sim"
    assert loaded.source == "ROS params of /robot/server"
    assert "waiting up to 10 s for the private params of /robot/server" in caplog.text


def test_a_master_that_never_answers_stops_start_up_saying_so(monkeypatch):
    monkeypatch.setenv("ROS_MASTER_URI", "http://127.0.0.1:{}".format(free_port()))
    started = time.monotonic()
    with pytest.raises(ConfigError) as info:
        launching.apply_private_params(config.Config(), "/server", wait=1.0)
    assert 0.9 < time.monotonic() - started < 5
    assert "did not answer within 1 s" in str(info.value) and "/server" in str(info.value)


def test_the_server_serves_on_the_port_roslaunch_gave_a_slow_master(tmp_path):
    port = free_port()
    params = {"server": {"port": port}, "mdns": {"enabled": False},
              "waypoints": {"file": str(tmp_path / "w.yaml")}}
    with slow_master(params, delay=2.5) as master:
        server = ServerProcess("--host", "127.0.0.1", "__name:=server", env={"ROS_MASTER_URI": master.uri})
        try:
            assert server.url == "http://127.0.0.1:{}".format(port)
            assert server.find("does not answer yet; waiting up to")
        finally:
            server.kill()
