"""Names in the owner's language through a real ``flask-move-server --sim`` (issue 22, item 6).

"Küche" and "Mum's room" go through the HTTP API (percent-encoded in paths, composed or not),
into the files on disk (readable, composed), and back as typed; robotctl and record-waypoints
send and show them; bad names are refused with the name as typed and change nothing. One server
for the module: the waypoint tests first, then the maps (mapping, save, rename, use).
"""

import os
import subprocess
import sys
import unicodedata
from urllib.parse import quote

import pytest
import requests

from flask_move_server.recorder.savers import ServerSaver
from flask_move_server.robotctl import cli as robotctl_cli
from flask_move_server.robotctl.api import ExitStatus, RobotClient
from tests.conftest import ROOT, ServerProcess, SimReads, free_port, stop_process, wait_for
from tests.test_recorder import Rig

NFD_KUCHE = unicodedata.normalize("NFD", "Küche")
CHARSET_JSON = "application/json; charset=utf-8"


class NamesSim(SimReads, ServerProcess):
    """The simulated robot on its own master, with a waypoints file (and maps/ beside it) in ``folder``."""

    def __init__(self, folder):
        self.folder = folder
        self.waypoints = folder / "waypoints.yaml"
        self.waypoints.write_text("waypoints:\n  dock: [0.0, 0.0, 0.0]\n  kitchen: [1.0, 0.5, 0.0]\n")
        (folder / "sim.yaml").write_text("sim:\n  speed_factor: 4.0\n")
        env = {"ROS_MASTER_URI": "http://127.0.0.1:{}".format(free_port()), "ROS_HOME": str(folder),
               "ROS_LOG_DIR": str(folder / "log"), "ROS_IP": "127.0.0.1"}
        super().__init__("--sim", "--config", str(folder / "sim.yaml"), "--host", "127.0.0.1", "--port", "0",
                         "--no-mdns", "--waypoints", str(self.waypoints), env=env, start_timeout=60)
        wait_for(lambda: self.get("/health").json().get("move_base") == "ready", timeout=30, message="move_base")

    def call(self, method, path, body=None):
        return requests.request(method, self.url + path, json=body, timeout=30)


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = NamesSim(tmp_path_factory.mktemp("names"))
    yield server
    stop_process(server.proc)


def robotctl(sim, *args):
    return robotctl_cli.main(["--url", sim.url, "--request-timeout", "30", *args])


# waypoints --------------------------------------------------------------------------------------------


def test_a_unicode_waypoint_goes_in_by_url_lands_readable_in_the_file_and_comes_back_as_typed(sim):
    put = sim.call("PUT", "/waypoints/K%C3%BCche", {"x": 1.5, "y": -0.5, "yaw": 0.25})
    assert put.status_code == 201 and put.headers["Content-Type"] == CHARSET_JSON
    assert '"name":"Küche"'.encode() in put.content.replace(b" ", b"")  # as typed, not "K\u00fcche"
    assert "  Küche: [1.5, -0.5, 0.25]\n" in sim.waypoints.read_text(encoding="utf-8")

    typed_on_a_mac = "/waypoints/" + quote(NFD_KUCHE)  # Ku%CC%88che: the same name
    assert sim.call("GET", typed_on_a_mac).json() == {"name": "Küche", "x": 1.5, "y": -0.5, "yaw": 0.25}
    for name in ("Mum's room", "Mum\u2019s room"):
        put = sim.call("PUT", "/waypoints/" + quote(name, safe=""), {"x": 2.0, "y": 1.0, "yaw": 0.0})
        assert put.status_code == 201
    listed = [w["name"] for w in sim.call("GET", "/waypoints").json()["waypoints"]]
    assert listed == ["dock", "kitchen", "Küche", "Mum's room", "Mum\u2019s room"]
    assert '  "Mum\'s room": [2.0, 1.0, 0.0]\n' in sim.waypoints.read_text(encoding="utf-8")

    assert sim.call("DELETE", typed_on_a_mac).status_code == 204
    assert "Küche" not in sim.waypoints.read_text(encoding="utf-8")


@pytest.mark.parametrize("path, shown", [
    ("/waypoints/K%C3%BCche%2F..%2Fmaps", '"Küche/../maps"'),
    ("/waypoints/K%C3%BCche%E2%80%AE", '"Küche\\u202e"'),
    ("/waypoints/%20K%C3%BCche", '" Küche"'),
])
def test_a_bad_name_is_refused_quoted_as_typed_and_changes_nothing(sim, path, shown):
    before = sim.waypoints.read_bytes()
    answer = sim.call("PUT", path, {"x": 1.0, "y": 1.0, "yaw": 0.0})
    body = answer.json()
    assert answer.status_code == 400 and body["error"] == "bad_waypoint", body
    assert body["message"].startswith("Invalid waypoint name {}: ".format(shown)), body["message"]
    assert body["message"].endswith('e.g. "Küche" or "Mum\'s room".')
    assert sim.waypoints.read_bytes() == before


def test_a_goal_by_a_decomposed_name_goes_to_the_place(sim):
    sim.call("PUT", "/waypoints/K%C3%BCche", {"x": 1.0, "y": 0.5, "yaw": 0.0})
    answer = sim.call("POST", "/goto", {"name": NFD_KUCHE})
    assert answer.status_code == 202 and answer.json()["target"] == "Küche", answer.json()
    assert sim.call("POST", "/stop").status_code == 200


# robotctl and record-waypoints -------------------------------------------------------------------------


def test_robotctl_adds_lists_and_removes_names_as_typed(sim, capsys):
    assert robotctl(sim, "waypoints", "add", "台所", "3", "1", "0") == ExitStatus.OK
    assert capsys.readouterr().out.startswith("added 台所 at (x 3.00, y 1.00, yaw 0.00")
    assert robotctl(sim, "waypoints") == ExitStatus.OK
    rows = capsys.readouterr().out.splitlines()
    by_name = {row.split("  ")[0].rstrip(): row for row in rows[1:]}
    assert {"台所", "Küche", "Mum's room"} <= set(by_name)
    # "台所" takes four terminal columns: the coordinates still line up under the header's
    assert by_name["台所"].replace("台所", "xxxx").index("3.00") == by_name["Küche"].replace("Küche", "xxxxx").index(
        "1.00") == rows[0].index("X [m]") + 1
    assert robotctl(sim, "waypoints", "rm", unicodedata.normalize("NFD", "Mum's room")) == ExitStatus.OK
    assert "Mum's room" not in [w["name"] for w in sim.call("GET", "/waypoints").json()["waypoints"]]
    assert robotctl(sim, "waypoints", "rm", "küche") == ExitStatus.NOT_FOUND
    assert "No waypoint named 'küche'. Did you mean: 'Küche'" in capsys.readouterr().err


def test_robotctl_on_a_terminal_that_cannot_show_a_name_escapes_it(sim):
    listed = subprocess.run([sys.executable, "-m", "flask_move_server.robotctl.cli", "--url", sim.url, "waypoints"],
                            env=dict(os.environ, PYTHONIOENCODING="ascii", PYTHONPATH=ROOT), cwd=ROOT,
                            capture_output=True, text=True, timeout=60)
    assert listed.returncode == 0, listed.stderr
    assert "K\\xfcche" in listed.stdout and "Traceback" not in listed.stderr


def test_the_recorder_saves_and_renames_through_the_server_under_the_names_typed(sim, ros_node, unique_name,
                                                                                 tmp_path):
    rig = Rig(unique_name, tmp_path / "unused.yaml", saver=ServerSaver(RobotClient(sim.url, timeout=30)))
    try:
        rig.click(-1.0, 2.0)
        rig.session.handle_line("Oma's Küche")  # the click's name: an apostrophe is no shell quote here
        assert rig.said[-1].startswith("Saved Oma's Küche at x -1.00, y 2.00")
        rig.session.handle_line('rename "Oma\'s Küche" Бабушка')  # quoted with ", the apostrophe kept
        assert rig.said[-1] == "Renamed Oma's Küche to Бабушка."
        rig.session.handle_line("here Mum\u2019s room")
        rig.session.handle_line("list")
    finally:
        rig.close()
    listed = {w["name"]: w for w in sim.call("GET", "/waypoints").json()["waypoints"]}
    assert listed["Бабушка"]["x"] == -1.0 and "Oma's Küche" not in listed
    assert "  Бабушка: [-1.0, 2.0, 0.0]\n" in sim.waypoints.read_text(encoding="utf-8")


# maps -------------------------------------------------------------------------------------------------


def test_a_map_saved_renamed_and_used_under_unicode_names(sim):
    maps = sim.folder / "maps"
    assert sim.call("POST", "/mode", {"mode": "mapping", "wait": 60}).status_code == 200
    saved = sim.call("POST", "/maps", {"name": NFD_KUCHE})
    assert saved.status_code == 201 and saved.json()["map"]["name"] == "Küche", saved.json()
    assert {"Küche.yaml", "Küche.pgm"} <= set(os.listdir(str(maps)))  # composed on disk
    before = sorted(os.listdir(str(maps)))
    twin = sim.call("POST", "/maps", {"name": "KÜCHE", "overwrite": True})
    assert twin.status_code == 409 and "'Küche' is saved, and map names must differ in more than case" in \
        twin.json()["message"]
    bad = sim.call("POST", "/maps", {"name": "../Küche"}).json()
    assert bad["error"] == "bad_map_name" and bad["message"].startswith('Invalid map name "../Küche": \'/\' is not')
    assert sorted(os.listdir(str(maps))) == before

    renamed = sim.call("PATCH", "/maps/" + quote(NFD_KUCHE), {"name": "Mum's room"})
    assert renamed.status_code == 200 and renamed.json()["map"]["name"] == "Mum's room", renamed.json()
    assert "Mum's room.yaml" in os.listdir(str(maps)) and "Küche.yaml" not in os.listdir(str(maps))
    assert sim.call("GET", "/maps/Mum%27s%20room").json()["name"] == "Mum's room"

    curly = sim.call("POST", "/mode", {"mode": "navigation", "map": "Mum\u2019s room"})
    assert curly.status_code == 404 and 'Did you mean: "Mum\'s room"?' in curly.json()["message"], curly.json()
    used = sim.call("POST", "/mode", {"mode": "navigation", "map": "Mum's room", "wait": 60})
    assert used.status_code == 200 and used.json()["map"] == "Mum's room", used.json()
    assert sim.call("GET", "/maps").json()["active"] == "Mum's room"


def test_robotctl_commands_take_unicode_names(sim, capsys):
    assert robotctl(sim, "map", "list") == ExitStatus.OK
    assert "* Mum's room" in capsys.readouterr().out
    assert robotctl(sim, "map", "rm", "Mum's room") == ExitStatus.ERROR  # the map in use
    assert "Mum's room is the map in use" in capsys.readouterr().err
    marked = sim.call("PUT", "/waypoints/" + quote("Küche"), {"from": "current"})  # a place on this map
    assert marked.status_code in (200, 201), marked.json()
    assert robotctl(sim, "pose", NFD_KUCHE) == ExitStatus.OK
    assert robotctl(sim, "goto", NFD_KUCHE) == ExitStatus.OK
    assert sim.status()["navigation"]["target"] == "Küche"
    assert robotctl(sim, "stop") == ExitStatus.OK

    assert robotctl(sim, "map", "start") == ExitStatus.OK
    assert robotctl(sim, "map", "save", "台所") == ExitStatus.OK
    assert "saved map 台所" in capsys.readouterr().out
    assert "image: 台所.pgm\n" in (sim.folder / "maps" / "台所.yaml").read_text(encoding="utf-8")
    assert robotctl(sim, "map", "rm", "台所") == ExitStatus.OK
    assert "台所.yaml" not in os.listdir(str(sim.folder / "maps"))
    assert robotctl(sim, "map", "use", "Mum’s room") == ExitStatus.NOT_FOUND
    assert robotctl(sim, "map", "use", "Mum's room") == ExitStatus.OK
    assert sim.call("GET", "/mode").json()["map"] == "Mum's room"
