"""robot.local and the API over real multicast between two hosts.

The server process (with its own ROS master) runs in one network namespace, the
client side in another, joined by a veth pair (tests/netns.py). Everything the
client does runs there as ``python -m tests.mdns_probe ...``. The tests share one
server and run in file order: the address change and SIGTERM come last.
"""

import json
import os
import subprocess
import sys
import threading

import pytest

from flask_move_server import API_VERSION, __version__
from tests import netns
from tests.conftest import ROOT, wait_for

pytestmark = pytest.mark.netns

TOKEN = "lan-test-token"
HTTP_NAME = "robot._http._tcp.local."


class Output:
    """Collects a process's output lines in a thread, so its pipe never fills."""

    def __init__(self, stream, parse=False):
        self.lines = []
        self._parse = parse
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream):
        for line in stream:
            self.lines.append(json.loads(line) if self._parse else line.rstrip("\n"))

    def wait_for(self, predicate, timeout, message, start=0):
        """The first line from index ``start`` on matching ``predicate``, waiting up to ``timeout`` seconds."""
        return wait_for(lambda: next((x for x in self.lines[start:] if predicate(x)), None), timeout, message=message)

    def text(self):
        return "\n".join(str(x) for x in self.lines)


@pytest.fixture(scope="module")
def lan():
    reason = netns.unavailable_reason()
    if reason:
        pytest.skip(reason)
    with netns.Lan() as lan:
        yield lan


def probe(lan, *args, timeout=30):
    """Run ``tests.mdns_probe ARGS`` on the client side; its JSON output."""
    result = lan.run(netns.CLIENT, [sys.executable, "-m", "tests.mdns_probe", *args], timeout=timeout,
                     cwd=ROOT, capture_output=True, text=True, env=dict(os.environ, ROBOT_TOKEN=TOKEN))
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


def _stop(proc):
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@pytest.fixture(scope="module")
def server(lan, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("lan_server")
    (tmp / "robot.yaml").write_text("mdns:\n  publish_hostname: always\n")
    env = dict(os.environ, ROS_MASTER_URI="http://127.0.0.1:11311", ROS_IP="127.0.0.1", ROS_HOME=str(tmp),
               FLASK_MOVE_SERVER_TOKEN=TOKEN, PYTHONUNBUFFERED="1")
    env.pop("ROS_HOSTNAME", None)
    master = lan.popen(netns.SERVER, ["rosmaster", "--core", "-p", "11311"], env=env,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    argv = [sys.executable, "-m", "flask_move_server", "--config", str(tmp / "robot.yaml"),
            "--waypoints", str(tmp / "waypoints.yaml"), "--host", "0.0.0.0", "--port", "0"]
    proc = lan.popen(netns.SERVER, argv, env=env, cwd=ROOT, stdout=subprocess.DEVNULL,
                     stderr=subprocess.PIPE, text=True)
    log = Output(proc.stderr)
    try:
        line = log.wait_for(lambda x: "serving the API on" in x, 60, "the server to serve")
        proc.port = int(line.split("serving the API on http://0.0.0.0:")[1].split()[0])
        proc.log = log
        log.wait_for(lambda x: "mDNS: advertising" in x, 30, "the server to advertise")
        yield proc
    finally:
        _stop(proc)
        _stop(master)


@pytest.fixture(scope="module")
def browser(lan):
    proc = lan.popen(netns.CLIENT, [sys.executable, "-m", "tests.mdns_probe", "browse", "_http._tcp.local."],
                     cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        yield Output(proc.stdout, parse=True)
    finally:
        _stop(proc)


def test_raw_a_query_for_robot_local_answers_the_server_address(lan, server):
    assert probe(lan, "a-query", "robot.local.", "3") == [lan.addresses[netns.SERVER]]


def test_browsing_http_services_finds_the_robot_on_the_served_port(lan, server, browser):
    event = browser.wait_for(lambda e: e["name"] == HTTP_NAME and e.get("port"), 15, "the robot in the browser")
    assert event["port"] == server.port
    assert event["addresses"] == [lan.addresses[netns.SERVER]]


def test_discover_lists_the_robot_with_what_a_client_needs(lan, server):
    robots = probe(lan, "discover", "3")
    assert robots == [{
        "name": "robot", "host": "robot.local", "addresses": [lan.addresses[netns.SERVER]], "port": server.port,
        "token_required": True, "version": __version__, "api_version": API_VERSION,
    }]


def test_status_answers_at_the_address_robot_local_resolves_to(lan, server):
    result = probe(lan, "get-local", "robot.local", str(server.port), "/status")
    assert result["address"] == lan.addresses[netns.SERVER]
    assert result["status"] == 200
    assert "navigation" in result["body"]


def test_a_second_robot_with_the_same_names_is_renamed_and_told_why(lan, server):
    proc = lan.popen(netns.CLIENT, [sys.executable, "-m", "tests.mdns_probe", "advertise", "robot", "robot", "8080"],
                     cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        published = json.loads(proc.stdout.readline())
    finally:
        proc.stdin.close()
        _stop(proc)
    log = proc.stderr.read()
    assert published["hostname"] == "robot-2.local"
    assert set(published["instances"].values()) == {"robot-2._flask-move._tcp.local.", "robot-2._http._tcp.local."}
    assert "host name conflict: robot.local is already used by another device at {}".format(
        lan.addresses[netns.SERVER]) in log
    assert "mdns.hostname" in log
    assert probe(lan, "a-query", "robot.local.", "3") == [lan.addresses[netns.SERVER]]


def test_a_new_server_address_is_seen_from_the_other_host_within_10_s(lan, server):
    new_address = lan.subnet + ".7"
    lan.change_address(netns.SERVER, new_address)
    wait_for(lambda: probe(lan, "a-query", "robot.local.", "1") == [new_address], 10,
             message="robot.local to answer with {}".format(new_address))


def test_sigterm_withdraws_the_service_from_browsers_at_once(lan, server, browser):
    address = lan.addresses[netns.SERVER]
    server.log.wait_for(lambda x: "mDNS: advertising" in x and address in x, 15, "advertising at " + address)
    browser.wait_for(lambda e: e["name"] == HTTP_NAME and address in e.get("addresses", []),
                     15, "the browser to see the robot at its current address")
    seen = len(browser.lines)
    server.terminate()
    assert server.wait(20) == 0, server.log.text()
    browser.wait_for(lambda e: e["event"] == "removed" and e["name"] == HTTP_NAME, 5,
                     "the robot to leave the browser; browser saw:\n{}\nserver log:\n{}".format(
                         browser.text(), server.log.text()), start=seen)
