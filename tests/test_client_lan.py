"""robotctl on another host of a real LAN: `discover`, and robot.local without nss-mdns.

Reuses the two-namespace LAN and the advertising server of test_mdns_lan.py
(fixtures imported, so this module gets its own pair). The client namespace's
resolver knows nothing of .local, so reaching http://robot.local:PORT takes
robotctl's own mDNS fallback.
"""

import json
import os
import sys

import pytest

from flask_move_server import __version__
from tests import netns
from tests.conftest import ROOT
from tests.test_mdns_lan import TOKEN, lan, server  # noqa: F401 - fixtures

pytestmark = pytest.mark.netns


def robotctl(network, *args):
    env = dict(os.environ)
    env.pop("ROBOT_URL", None)
    env.pop("ROBOT_TOKEN", None)
    return network.run(netns.CLIENT, [sys.executable, "-m", "flask_move_server.robotctl.cli", *args], timeout=60,
                   cwd=ROOT, capture_output=True, text=True, env=env)


def test_discover_lists_the_robot_on_the_lan(lan, server):  # noqa: F811
    result = robotctl(lan, "discover", "--wait", "3")
    assert result.returncode == 0, result.stderr
    header, *rows = result.stdout.splitlines()
    assert header.split() == ["NAME", "URL", "TOKEN", "VERSION"]
    assert [row.split() for row in rows] == [
        ["robot", "http://robot.local:{}".format(server.port), "required", __version__]]


def test_robot_local_answers_through_robotctls_own_mdns_lookup(lan, server):  # noqa: F811
    url = "http://robot.local:{}".format(server.port)
    result = robotctl(lan, "--url", url, "--token", TOKEN, "status", "--json")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["navigation"]["state"] == "idle"

    result = robotctl(lan, "--url", url, "status")
    assert result.returncode == 4
    assert "needs a token: pass --token TOKEN or set ROBOT_TOKEN" in result.stderr


def test_no_robot_by_that_name_suggests_discover(lan, server):  # noqa: F811
    result = robotctl(lan, "--url", "http://nobody-here.local:5000", "status")
    assert result.returncode == 3
    assert result.stderr.startswith("robotctl: no robot answers at http://nobody-here.local:5000")
    assert "robotctl discover" in result.stderr and len(result.stderr.splitlines()) == 1
