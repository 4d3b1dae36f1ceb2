"""The map routes without ROS: /maps, /map, saving, per-map waypoints, against stand-ins.

The maps folder, the waypoint store and the event bus are the real ones on temporary files; the
mode manager and the live map are tests/fake_maps.py. The real map topic: tests/test_map_source.py.
"""

import os
import subprocess

import pytest
import yaml

from flask_move_server.core.events import EventBus
from flask_move_server.core.geometry import Pose2D
from flask_move_server.maps.catalogue import MapCatalogue
from flask_move_server.maps.mapfile import Grid
from flask_move_server.maps.service import MapService
from flask_move_server.modes.manager import ModeManager
from flask_move_server.web import create_app
from tests.fake_maps import FakeMapSource, FakeModes
from tests.fake_robot import FakeRobot
from tests.robot_fixtures import SEED


def room(width=40, height=30, wall_at=None):
    """A 5 cm grid, unknown but for a walled room of 20 x 10 cells at column 10, row 10."""
    cells = bytearray(b"\xff" * (width * height))
    for row in range(10, 20):
        for col in range(10, 30):
            edge = row in (10, 19) or col in (10, 29) or col == wall_at
            cells[row * width + col] = 100 if edge else 0
    return Grid(width, height, 0.05, -1.0, -0.5, bytes(cells))


@pytest.fixture
def robot():
    return FakeRobot()


@pytest.fixture
def events():
    return EventBus()


@pytest.fixture
def modes(events):
    return FakeModes(events, mode="mapping")


@pytest.fixture
def source():
    return FakeMapSource(room())


@pytest.fixture
def catalogue(robot_config):
    return MapCatalogue(robot_config.maps_folder())


@pytest.fixture
def service(catalogue, store, source, modes, events):
    return MapService(catalogue, store, source, modes=modes, events=events, margin=0.1, save_timeout=0.2)


@pytest.fixture
def app(robot_config, robot, store, events, service):
    return create_app(robot_config, robot, store, events=events, maps=service)


def error_of(response):
    body = response.get_json()
    assert body["status"] == "error", body
    return response.status_code, body["error"]


def files_in(folder):
    return sorted(os.listdir(folder)) if os.path.isdir(folder) else []


def mark_seed(client):
    """Mark the seed's three places while mapping, as the page's Mark does."""
    for name, place in yaml.safe_load(SEED)["waypoints"].items():
        r = client.put("/waypoints/" + name, json=dict(zip(("x", "y", "yaw"), place)))
        assert r.status_code in (200, 201), r.get_json()


# saving ------------------------------------------------------------------------------------


def test_saving_writes_the_pair_lists_it_with_the_places_marked_while_mapping(client, catalogue, robot_config,
                                                                              service):
    assert client.get("/maps").get_json() == {"maps": [], "active": None}
    assert client.get("/waypoints").get_json()["waypoints"] == []  # not the waypoints file's: another frame
    mark_seed(client)
    r = client.post("/maps", json={"name": "flat"})
    assert r.status_code == 201, r.get_json()
    body = r.get_json()
    assert body["map"]["name"] == "flat" and body["map"]["width"] == 40 and body["adopted_waypoints"] is False
    assert body["map"]["waypoints"] == 3
    assert files_in(catalogue.folder) == ["flat.pgm", "flat.waypoints.yaml", "flat.yaml"]
    assert yaml.safe_load(open(catalogue.waypoints_path("flat"))) == yaml.safe_load(SEED)
    assert open(robot_config.waypoints.file).read() == SEED  # the single file is never written while mapping
    listed = client.get("/maps").get_json()
    assert [m["name"] for m in listed["maps"]] == ["flat"] and listed["active"] is None
    assert client.get("/maps/flat").get_json()["resolution"] == 0.05


def test_a_map_saved_with_no_marks_has_no_places_and_adopts_none_of_the_single_file(client, catalogue):
    r = client.post("/maps", json={"name": "flat"})
    assert r.status_code == 201 and r.get_json()["adopted_waypoints"] is False
    assert r.get_json()["map"]["waypoints"] == 0
    assert not os.path.exists(catalogue.waypoints_path("flat"))


def test_overwriting_a_map_replaces_its_places_by_the_marks_and_keeps_the_old_ones_in_bak(client, catalogue):
    mark_seed(client)
    client.post("/maps", json={"name": "flat"})
    client.delete("/waypoints/office")
    client.delete("/waypoints/kitchen")
    r = client.post("/maps", json={"name": "flat", "overwrite": True})
    assert r.status_code == 201 and r.get_json()["map"]["waypoints"] == 1
    assert yaml.safe_load(open(catalogue.waypoints_path("flat")))["waypoints"] == {"dock": [0.0, 0.0, 0.0]}
    assert yaml.safe_load(open(catalogue.waypoints_path("flat") + ".bak")) == yaml.safe_load(SEED)


def test_an_existing_name_needs_overwrite(client, source, catalogue):
    client.post("/maps", json={"name": "flat"})
    source.publish(room(wall_at=20))
    assert error_of(client.post("/maps", json={"name": "flat"})) == (409, "map_exists")
    assert catalogue.load("flat").value(20, 15) == 0  # untouched
    assert client.post("/maps", json={"name": "flat", "overwrite": True}).status_code == 201
    assert catalogue.load("flat").value(20, 15) == 100


def test_with_modes_off_the_map_an_outside_stack_publishes_is_saved(robot_config, robot, store, events, source,
                                                                     catalogue):
    robot_config.modes.stack = "none"  # the owner runs gmapping with their own launch file
    modes = ModeManager(robot_config, None)
    service = MapService(catalogue, store, source, modes=modes, events=events, margin=0.1, save_timeout=0.2)
    client = create_app(robot_config, robot, store, events=events, modes=modes, maps=service).test_client()
    r = client.post("/maps", json={"name": "flat"})
    assert r.status_code == 201, r.get_json()
    assert files_in(catalogue.folder) == ["flat.pgm", "flat.waypoints.yaml", "flat.yaml"]
    source.publish(room(wall_at=20))
    r = client.post("/maps", json={"name": "flat", "overwrite": True, "then": "navigation"})
    assert r.status_code == 409 and r.get_json()["error"] == "modes_off"  # it cannot switch: nothing saved
    assert catalogue.load("flat").value(20, 15) == 0


def test_saving_without_a_name_says_the_name_is_required(client, catalogue):
    r = client.post("/maps", json={})
    assert error_of(r) == (400, "bad_request") and r.get_json()["message"] == "Field 'name' is required."
    assert files_in(catalogue.folder) == []


def test_saving_outside_mapping_mode_is_refused_and_writes_nothing(client, modes, catalogue):
    modes.mode = "navigation"
    status, code = error_of(client.post("/maps", json={"name": "flat"}))
    assert (status, code) == (409, "wrong_mode")
    assert "mapping" in client.post("/maps", json={"name": "flat"}).get_json()["message"]
    assert files_in(catalogue.folder) == []


def test_no_map_to_save_is_a_503_asking_whether_mapping_runs(client, source, catalogue):
    source.grid = None
    r = client.post("/maps", json={"name": "flat"})
    assert error_of(r) == (503, "no_map_received") and "is mapping running?" in r.get_json()["message"]
    assert files_in(catalogue.folder) == []


@pytest.mark.parametrize("body", [
    {"name": ".hidden"}, {"name": "x.waypoints"}, {"name": "a/b"}, {"name": ""}, {"name": "x" * 65},
])
def test_bad_map_names_are_400_and_write_nothing(client, catalogue, body):
    assert error_of(client.post("/maps", json=body)) == (400, "bad_map_name")
    assert files_in(catalogue.folder) == []


@pytest.mark.parametrize("body", [
    {}, {"name": 5}, {"name": "flat", "overwrite": "yes"}, {"name": "flat", "then": "mapping"}, {"nmae": "flat"},
])
def test_malformed_save_bodies_are_400(client, body):
    assert error_of(client.post("/maps", json=body)) == (400, "bad_request")


def test_then_navigation_switches_to_the_saved_map_and_its_waypoints_are_served(client, modes, robot_config,
                                                                                catalogue):
    r = client.post("/maps", json={"name": "flat", "then": "navigation"})
    assert r.status_code == 201 and r.get_json()["mode"]["map"] == "flat"
    assert modes.calls == [("switch", "navigation", "flat")]
    client.put("/waypoints/sofa", json={"x": 1, "y": 1, "yaw": 0})
    assert "sofa" in open(catalogue.waypoints_path("flat")).read()
    assert "sofa" not in open(robot_config.waypoints.file).read()
    assert client.get("/status").get_json()["waypoints"]["file"] == catalogue.waypoints_path("flat")
    assert client.get("/maps").get_json()["active"] == "flat"


def test_then_navigation_keeps_the_robot_where_mapping_had_it_not_at_the_dock(client, modes, robot):
    """The saved map has the mapping's frame, so the pose SLAM had is right; the dock would not be."""
    robot.pose = Pose2D(3.0, 1.5, 0.7)
    client.post("/maps", json={"name": "flat", "then": "navigation"})
    modes.mode, robot.pose = "mapping", None  # mapping again; pose unknown: the switch falls back to the dock
    client.post("/maps", json={"name": "flat", "overwrite": True, "then": "navigation"})
    client.post("/maps", json={"name": "other"})
    assert modes.poses == [Pose2D(3.0, 1.5, 0.7), None]


# the folder cannot be written ----------------------------------------------------------------


def test_a_file_where_the_folder_should_be_is_a_503_map_file(client, robot_config):
    with open(robot_config.maps_folder(), "w") as f:
        f.write("not a folder\n")
    r = client.post("/maps", json={"name": "flat"})
    assert error_of(r) == (503, "map_file") and robot_config.maps_folder() in r.get_json()["message"]


@pytest.fixture
def tiny_folder(tmp_path):
    """A 64 kB tmpfs (a full disk) mounted at the maps folder; root only, as this suite runs."""
    folder = tmp_path / "maps"
    folder.mkdir()
    subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(folder)], check=True)
    yield str(folder)
    subprocess.run(["umount", str(folder)], check=True)


def test_a_full_folder_is_a_503_map_file_and_leaves_nothing_half_written(client, source, tiny_folder):
    source.publish(room(width=400, height=300))  # a 120 kB image for a 64 kB disk
    r = client.post("/maps", json={"name": "flat"})
    assert error_of(r) == (503, "map_file") and "No space left" in r.get_json()["message"]
    assert files_in(tiny_folder) == []
    assert client.get("/maps").get_json()["maps"] == []


def test_a_read_only_folder_is_a_503_map_file(client, tiny_folder):
    subprocess.run(["mount", "-o", "remount,ro", tiny_folder], check=True)
    r = client.post("/maps", json={"name": "flat"})
    assert error_of(r) == (503, "map_file") and "Read-only" in r.get_json()["message"]
    assert files_in(tiny_folder) == []


# delete, rename, describe ----------------------------------------------------------------------


def test_delete_and_rename_refuse_the_active_map(client, modes):
    client.post("/maps", json={"name": "flat"})
    modes.switch("navigation", "flat")
    assert error_of(client.delete("/maps/flat")) == (409, "map_in_use")
    assert error_of(client.patch("/maps/flat", json={"name": "home"})) == (409, "map_in_use")
    assert client.get("/maps/flat").get_json()["active"] is True


def test_rename_moves_the_waypoints_and_delete_removes_everything(client, catalogue):
    mark_seed(client)
    client.post("/maps", json={"name": "flat"})
    r = client.patch("/maps/flat", json={"name": "home"})
    assert r.status_code == 200 and r.get_json()["map"]["name"] == "home"
    assert r.get_json()["map"]["waypoints"] == 3
    assert files_in(catalogue.folder) == ["home.pgm", "home.waypoints.yaml", "home.yaml"]
    assert client.delete("/maps/home").status_code == 204
    assert files_in(catalogue.folder) == []
    r = client.get("/maps/home")
    assert error_of(r) == (404, "unknown_map")


def test_a_rename_to_a_bad_or_taken_name_is_refused_and_changes_nothing(client, catalogue):
    client.post("/maps", json={"name": "garage"})
    mark_seed(client)
    client.post("/maps", json={"name": "flat"})
    assert error_of(client.patch("/maps/flat", json={"name": ".hidden"})) == (400, "bad_map_name")
    assert error_of(client.patch("/maps/flat", json={"name": "garage"})) == (409, "map_exists")
    assert error_of(client.patch("/maps/flat", json={})) == (400, "bad_request")
    assert files_in(catalogue.folder) == ["flat.pgm", "flat.waypoints.yaml", "flat.yaml", "garage.pgm",
                                          "garage.yaml"]


def test_unknown_maps_are_404_with_close_names(client):
    client.post("/maps", json={"name": "flat"})
    r = client.get("/maps/flta")
    assert error_of(r) == (404, "unknown_map") and "'flat'" in r.get_json()["message"]
    assert error_of(client.delete("/maps/nope")) == (404, "unknown_map")
    assert error_of(client.get("/maps/nope/image")) == (404, "unknown_map")
    assert error_of(client.patch("/maps/nope", json={"name": "x"})) == (404, "unknown_map")


# images ------------------------------------------------------------------------------------------


def test_a_saved_maps_image_is_a_png_with_an_etag_and_a_304_when_unchanged(client):
    client.post("/maps", json={"name": "flat"})
    r = client.get("/maps/flat/image")
    assert r.status_code == 200 and r.mimetype == "image/png" and r.data.startswith(b"\x89PNG")
    assert r.headers["Cache-Control"] == "no-cache" and r.headers["ETag"]
    again = client.get("/maps/flat/image", headers={"If-None-Match": r.headers["ETag"]})
    assert again.status_code == 304 and again.data == b""
    # A cache that marks the tag weak (some proxies do) still gets the 304: If-None-Match compares weakly.
    weak = client.get("/maps/flat/image", headers={"If-None-Match": "W/" + r.headers["ETag"]})
    assert weak.status_code == 304 and weak.data == b""
    other = client.get("/maps/flat/image", headers={"If-None-Match": 'W/"0-0", "elsewhere"'})
    assert other.status_code == 200 and other.data == r.data


def test_the_live_map_says_where_its_crop_is_and_a_304_renders_nothing(client, source):
    meta = client.get("/map").get_json()
    # the room: columns 10..29, rows 10..19, 2 cells of margin (0.1 m), origin (-1, -0.5)
    assert (meta["width"], meta["height"], meta["version"]) == (24, 14, 1)
    assert meta["origin"] == pytest.approx([-1.0 + 8 * 0.05, -0.5 + 8 * 0.05, 0.0])
    assert (meta["mode"], meta["map"]) == ("mapping", None)
    r = client.get("/map/image")
    decoded = source.decoded
    assert client.get("/map/image", headers={"If-None-Match": r.headers["ETag"]}).status_code == 304
    assert source.decoded == decoded
    source.publish(room(wall_at=20))
    r2 = client.get("/map/image", headers={"If-None-Match": r.headers["ETag"]})
    assert r2.status_code == 200 and r2.headers["ETag"] != r.headers["ETag"] and r2.data != r.data


def test_no_live_map_is_a_404(client, source):
    source.grid = None
    assert error_of(client.get("/map")) == (404, "no_map")
    assert error_of(client.get("/map/image")) == (404, "no_map")


# waypoints follow the mode's map ------------------------------------------------------------------


def test_waypoints_follow_the_mode_and_every_change_is_an_event(client, modes, events, catalogue, robot_config):
    client.post("/maps", json={"name": "flat"})
    client.post("/maps", json={"name": "garage"})
    sub = events.subscribe(["waypoints"], replay=False)
    modes.switch("navigation", "garage")
    assert client.get("/waypoints").get_json()["waypoints"] == []
    assert sub.next(1) == ("waypoints", {"map": "garage", "version": 2})
    client.put("/waypoints/bench", json={"x": 2, "y": 1, "yaw": 0})
    assert sub.next(1) == ("waypoints", {"map": "garage", "version": 3})
    assert yaml.safe_load(open(catalogue.waypoints_path("garage")))["waypoints"] == {"bench": [2.0, 1.0, 0.0]}
    modes.switch("navigation")  # the stack's own map: the single waypoints file
    assert [w["name"] for w in client.get("/waypoints").get_json()["waypoints"]] == ["kitchen", "office", "dock"]
    assert client.get("/status").get_json()["waypoints"]["file"] == robot_config.waypoints.file
    assert sub.next(1) == ("waypoints", {"map": None, "version": 4})
    modes.switch("mapping")  # a new map being made: its own places, none yet
    assert client.get("/waypoints").get_json()["waypoints"] == []
    assert client.get("/status").get_json()["waypoints"]["file"] == os.path.join(
        os.path.dirname(robot_config.waypoints.file), "mapping.waypoints.yaml")
    assert sub.next(1) == ("waypoints", {"map": None, "version": 5})


def test_without_a_maps_service_the_app_still_lists_the_configured_folder(robot_config, store):
    app = create_app(robot_config, FakeRobot(), store)
    assert app.test_client().get("/maps").get_json() == {"maps": [], "active": None}
    assert error_of(app.test_client().get("/map")) == (404, "no_map")


def test_a_broken_waypoints_file_of_the_new_map_is_reported_and_never_overwritten(client, modes, catalogue):
    mark_seed(client)
    client.post("/maps", json={"name": "flat"})
    client.post("/maps", json={"name": "garage"})
    with open(catalogue.waypoints_path("garage"), "w") as f:
        f.write("waypoints: [oops\n")
    modes.switch("navigation", "garage")
    assert client.get("/waypoints").get_json()["waypoints"] == []
    assert "garage.waypoints.yaml" in client.get("/status").get_json()["waypoints"]["problem"]
    assert error_of(client.put("/waypoints/bench", json={"x": 1, "y": 1, "yaw": 0})) == (409, "waypoints_file")
    assert open(catalogue.waypoints_path("garage")).read() == "waypoints: [oops\n"
    modes.switch("navigation", "flat")
    assert len(client.get("/waypoints").get_json()["waypoints"]) == 3
    assert client.get("/status").get_json()["waypoints"]["problem"] is None


def test_an_edit_on_disk_of_the_active_maps_waypoints_is_served_and_told(client, modes, events, catalogue):
    mark_seed(client)
    client.post("/maps", json={"name": "flat"})
    modes.switch("navigation", "flat")
    client.get("/waypoints")
    sub = events.subscribe(["waypoints"], replay=False)
    with open(catalogue.waypoints_path("flat"), "w") as f:
        f.write("waypoints:\n  hall: [3.0, 1.0, 0.0]\n")
    assert [w["name"] for w in client.get("/waypoints").get_json()["waypoints"]] == ["hall"]
    kind, data = sub.next(1)
    assert kind == "waypoints" and data["map"] == "flat"


# robotctl map ------------------------------------------------------------------------------------


def test_robotctl_map_save_list_rm(app, capsys, modes, catalogue):
    from flask_move_server.robotctl import cli as robotctl
    from tests.conftest import serve

    with serve(app) as url:
        assert robotctl.main(["--url", url, "map", "list"]) == 0
        assert "no maps saved yet" in capsys.readouterr().out
        mark_seed(app.test_client())
        assert robotctl.main(["--url", url, "map", "save", "flat"]) == 0
        assert "saved map flat (2.0 x 1.5, with the 3 places marked while mapping)" in capsys.readouterr().out
        assert robotctl.main(["--url", url, "map", "save", "flat"]) == 1
        assert "'robotctl map save flat --overwrite' replaces it" in capsys.readouterr().err  # its words, not HTTP's
        assert robotctl.main(["--url", url, "map", "save", "flat", "--overwrite", "--then-navigate"]) == 0
        assert "switching to navigation on flat" in capsys.readouterr().out
        assert modes.calls == [("switch", "navigation", "flat")]
        assert robotctl.main(["--url", url, "map"]) == 0
        out = capsys.readouterr().out.splitlines()
        assert out[1].startswith("* flat") and out[1].split()[2:6] == ["2.0", "x", "1.5", "3"]
        assert robotctl.main(["--url", url, "map", "rm", "flat"]) == 1
        assert "flat is the map in use: switch to another first ('robotctl map use OTHER'" in capsys.readouterr().err
        assert robotctl.main(["--url", url, "map", "rm", "garage"]) == 5
        assert "No map named 'garage'. 'robotctl map list' lists them." in capsys.readouterr().err
        modes.switch("mapping")
        assert robotctl.main(["--url", url, "map", "rm", "flta"]) == 5
        assert "Did you mean: 'flat'" in capsys.readouterr().err
        assert robotctl.main(["--url", url, "map", "rm", "flat"]) == 0
        assert not catalogue.exists("flat")


def test_a_service_built_after_the_mode_was_restored_serves_that_maps_waypoints(catalogue, store, events, source,
                                                                                 robot_config):
    catalogue.save("flat", room())
    with open(catalogue.waypoints_path("flat"), "w") as f:
        f.write("waypoints:\n  hall: [3.0, 1.0, 0.0]\n")
    modes = FakeModes(events, mode="navigation", map_name="flat")
    service = MapService(catalogue, store, source, modes=modes, events=events)
    app = create_app(robot_config, FakeRobot(), store, events=events, maps=service)
    assert [w["name"] for w in app.test_client().get("/waypoints").get_json()["waypoints"]] == ["hall"]
    assert events.latest("waypoints") == {"map": "flat", "version": 1}


def test_marks_that_cannot_be_given_to_the_map_leave_no_map_behind(client, catalogue, service):
    with open(service.marks.path, "wb") as f:
        f.write(b"waypoints:\n  caf\xe9: [1, 2, 3]\n")  # not UTF-8: the copy cannot be made
    r = client.post("/maps", json={"name": "flat"})
    assert error_of(r) == (503, "map_file") and "the map was not saved" in r.get_json()["message"]
    assert files_in(catalogue.folder) == []


# the map the stack was configured with --------------------------------------------------------


@pytest.fixture
def with_demo(catalogue, store, source, modes, events, robot_config, robot):
    from flask_move_server.maps.configured import ConfiguredMap
    from tests.conftest import ROOT

    demo = ConfiguredMap("demo", os.path.join(ROOT, "config", "maps", "demo.yaml"))
    service = MapService(catalogue, store, source, modes=modes, events=events, margin=0.1, save_timeout=0.2,
                         configured=demo)
    return create_app(robot_config, robot, store, events=events, maps=service).test_client()


def test_the_configured_map_is_listed_first_and_its_name_cannot_be_taken(with_demo, catalogue):
    client = with_demo
    assert client.post("/maps", json={"name": "garage"}).status_code == 201
    listed = client.get("/maps").get_json()
    assert [(m["name"], m["source"]) for m in listed["maps"]] == [("demo", "configured"), ("garage", "saved")]
    assert listed["active"] is None  # mapping
    for name in ("demo", "DEMO"):
        r = client.post("/maps", json={"name": name})
        assert error_of(r) == (409, "map_exists") and "robot's own map" in r.get_json()["message"]
        assert error_of(client.patch("/maps/garage", json={"name": name})) == (409, "map_exists")
    assert error_of(client.delete("/maps/demo")) == (409, "map_configured")
    assert files_in(catalogue.folder) == ["garage.pgm", "garage.yaml"]


def test_a_saved_map_of_the_configured_maps_name_hides_it(with_demo, catalogue):
    catalogue.save("demo", room())  # dropped in before: the name means the saved map
    listed = with_demo.get("/maps").get_json()
    assert [(m["name"], m["source"]) for m in listed["maps"]] == [("demo", "saved")]
    assert with_demo.delete("/maps/demo").status_code == 204
    assert [m["source"] for m in with_demo.get("/maps").get_json()["maps"]] == ["configured"]
