"""The real server (``--sim``) serves the map in use and the maps folder: cli's wiring, end to end."""

import signal

import pytest

from flask_move_server.maps.catalogue import MapCatalogue
from flask_move_server.maps.render import render
from flask_move_server.sim import occupancy
from tests.conftest import ROOT, wait_for
from tests.test_sim_e2e import SimServer


@pytest.fixture
def sim(tmp_path):
    server = SimServer(tmp_path)
    yield server
    server.kill()


def test_the_sim_serves_its_map_with_an_etag_and_an_empty_maps_folder(sim, tmp_path):
    meta = wait_for(lambda: sim.get("/map").ok and sim.get("/map").json(), timeout=20, message="the map")
    demo = occupancy.load(ROOT + "/config/maps/demo.yaml")
    expected = render(demo, margin=1.0)
    assert (meta["width"], meta["height"], meta["resolution"]) == (expected.width, expected.height, 0.05)
    assert meta["origin"] == pytest.approx([expected.origin_x, expected.origin_y, 0.0])
    image = sim.get("/map/image")
    assert image.content == expected.png
    import requests

    again = requests.get(sim.url + "/map/image", headers={"If-None-Match": image.headers["ETag"]}, timeout=10)
    assert again.status_code == 304
    listed = sim.get("/maps").json()  # the sim's own map only: the folder is empty
    assert [(m["name"], m["source"]) for m in listed["maps"]] == [("demo", "configured")] and listed["active"] == "demo"
    assert MapCatalogue(str(tmp_path / "maps")).names() == []
    assert sim.stop(signal.SIGTERM) == 0


def test_hostile_map_files_in_the_folder_neither_flood_nor_stall_the_real_server(sim, tmp_path):
    from tests.test_maps_hostile import alias_bomb

    folder = tmp_path / "maps"  # the default: maps/ beside the waypoints file
    folder.mkdir(exist_ok=True)
    (folder / "bomb.yaml").write_text(alias_bomb())
    (folder / "deep.yaml").write_text("image: deep.pgm\nresolution: 0.05\norigin: " + "[" * 5000 + "]" * 5000 + "\n")
    (folder / "big.yaml").write_text("image: big.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnotes: [{}]\n".format(
        ",".join(["1.0"] * 700000)))  # 2.8 MB
    listed = sim.get("/maps")  # 10 s timeout: the big file alone took 14 s to parse
    assert listed.status_code == 200 and len(listed.content) < 4000, len(listed.content)
    assert {m["name"] for m in listed.json()["maps"] if m.get("problem")} == {"big", "bomb", "deep"}
    switch = sim.post("/mode", {"mode": "navigation", "map": "bomb"})
    assert switch.status_code == 503 and switch.json()["error"] == "map_file"
    assert len(sim.get("/mode").content) < 1000 and len(sim.get("/status").content) < 20000
    assert sim.post("/stop").status_code == 200
    assert sim.stop(signal.SIGTERM) == 0
