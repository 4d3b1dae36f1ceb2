"""The README's demo, as a new user meets it: its command blocks run top to bottom on a fresh ``--sim`` robot.

The commands of the blocks of "Try it" after ``make demo`` run in order as written, through bash,
with the demo's address swapped for the test server's (at the sim's speed factor). A block that
leaves the robot busy (a run paused, a stack still starting) makes a later command fail here as it
would for the user. Left out for time: the whole run takes 57-102 s here (load 9-15), the
exploration alone 39 s and the mapping tour's drives most of the rest, so the exploration is
started as the block starts it and then stopped, and the drives to coordinates are skipped.
``curl -N`` streams until Ctrl-C: it gets a few seconds and must have shown events.
"""

import json
import os
import re
import subprocess
import sys

import pytest

from tests.conftest import ROOT, stop_process, wait_for
from tests.test_sim_e2e import SimServer

README = os.path.join(ROOT, "README.md")
DEMO_URL = "http://127.0.0.1:5000"
STREAM_SECONDS = 3  # how long `curl -N` (ended by Ctrl-C in the README) is left to show events
COMMAND_TIMEOUT = 150  # s: the longest command left, a drive to a waypoint, takes seconds


def demo_blocks():
    """The command blocks of the README's "Try it" section after ``make demo``: lists of commands."""
    with open(README, encoding="utf-8") as f:
        section = f.read().split("\n## Try it", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```sh\n(.*?)```", section, re.S)
    assert blocks[0].startswith("make demo")
    return [[line for line in block.replace("\\\n", " ").splitlines() if line.strip()] for block in blocks[1:]]


def _as_run_here(command, url):
    """``command`` against ``url``, curl saying its status code last, robotctl the one beside this Python."""
    command = command.replace(DEMO_URL, url)
    command = command.replace(".venv/bin/robotctl", os.path.join(os.path.dirname(sys.executable), "robotctl"))
    return re.sub(r"^curl ", "curl -sS -w '\\n%{http_code}' ", command)


def _run(command, url):
    """(exit status or None when stopped like Ctrl-C, what it printed)."""
    streaming = " -N " in command
    try:
        done = subprocess.run(["bash", "-c", _as_run_here(command, url)], cwd=ROOT, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, timeout=STREAM_SECONDS if streaming else COMMAND_TIMEOUT)
    except subprocess.TimeoutExpired as stopped:
        assert streaming, "{} did not end within {} s".format(command, COMMAND_TIMEOUT)
        return None, (stopped.stdout or b"").decode("utf-8", "replace")
    return done.returncode, done.stdout.decode("utf-8", "replace")


@pytest.fixture(scope="module")
def fresh_demo(tmp_path_factory):
    server = SimServer(tmp_path_factory.mktemp("readme"))
    yield server
    stop_process(server.proc)


EXPLORING = re.compile(r"robotctl .*map explore (\S+) --wait")
DRIVING_TO_COORDINATES = re.compile(r"^curl -d '\{\"x\": .*\"wait\"")


def _explore_briefly(sim, name):
    """The block's exploration started (where a paused run made it a 409), then ended by /stop."""
    r = sim.post("/explore", {"save_as": name})
    assert r.status_code == 202, r.text
    wait_for(lambda: sim.get("/explore").json()["exploration"]["state"] == "exploring", timeout=30,
             message="the exploration to start")
    assert sim.post("/stop").status_code == 200
    wait_for(lambda: sim.get("/explore").json()["exploration"]["state"] == "canceled", timeout=30,
             message="the exploration to end")


def test_the_demo_blocks_work_top_to_bottom_as_written(fresh_demo):
    for number, block in enumerate(demo_blocks(), 1):
        for command in block:
            exploring = EXPLORING.search(command)
            if exploring:
                _explore_briefly(fresh_demo, exploring.group(1))
                continue
            if DRIVING_TO_COORDINATES.search(command):
                continue
            status, said = _run(command, fresh_demo.url)
            where = "block {}: {}\n{}".format(number, command, said[-600:])
            if status is None:
                assert "event: pose" in said, where
            elif command.startswith("curl "):
                assert status == 0 and said.rstrip().splitlines()[-1] in ("200", "201", "202"), where
            else:
                assert status == 0, where
    mode = fresh_demo.get("/mode").json()
    assert (mode["mode"], mode["map"], mode["state"]) == ("navigation", "flat", "running")
    assert [w["name"] for w in fresh_demo.get("/waypoints").json()["waypoints"]] == ["kitchen", "dock"]


def test_each_block_saves_its_map_under_a_name_of_its_own():
    """The exploration saved ``flat`` and the mapping block's save of ``flat`` answered 409."""
    commands = [c for b in demo_blocks() for c in b]
    explored = [m.group(1) for c in commands for m in (EXPLORING.search(c), re.search(r'"save_as": "(.*?)"', c)) if m]
    saves = [re.search(r"^curl -d '(.*?)' \S+/maps\s", c) for c in commands]
    saved = [json.loads(save.group(1))["name"] for save in saves if save]
    names = explored + saved + ["demo"]
    assert explored and saved and len({n.casefold() for n in names}) == len(names), names


def test_the_readme_writes_nothing_into_the_checkout():
    """``curl -o map.png`` left a map.png in the checkout: what the README saves goes elsewhere."""
    saved = [re.search(r"-o (\S+)", c).group(1) for b in demo_blocks() for c in b if " -o " in c]
    assert saved and all(os.path.isabs(path) for path in saved)


def _demo_waypoints(*make_args):
    """The waypoints file ``make demo`` would serve (make -n: nothing runs)."""
    made = subprocess.run(["make", "-n", "demo"] + list(make_args), cwd=ROOT, stdout=subprocess.PIPE,
                          text=True, check=True).stdout
    return re.search(r"flask-move-server --sim .*--waypoints (\S+)", made).group(1)


def test_two_demos_from_one_checkout_keep_their_own_state():
    assert _demo_waypoints() == "build/demo/waypoints.yaml"  # as the README says: build/demo/mode.json
    assert _demo_waypoints("DEMO_PORT=5001") == "build/demo-5001/waypoints.yaml"
    assert _demo_waypoints("DEMO_PORT=5002") == "build/demo-5002/waypoints.yaml"
