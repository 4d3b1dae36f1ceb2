"""Zones without ROS: what a zone may be, where it is kept, its cells in the mask, the API's answers.

The store is the real one on a temporary file, the app the real Flask app (a fake robot behind it,
with the real zones guard); what the costmaps and the simulated move_base do with the mask is
tests/test_zones_sim.py's and tests/test_nav_rules.py's.
"""

import math

import pytest

from flask_move_server.core.errors import BadZone, WaypointFileError
from flask_move_server.waypoints.store import WaypointStore
from flask_move_server.zones import MAX_POINTS, distance, make_zone
from flask_move_server.zones.guard import ZoneGuard
from flask_move_server.zones.mask import LETHAL, NO_OPINION, cells
from tests.fake_robot import FakeRobot

SQUARE = [[2.0, 1.0], [3.0, 1.0], [3.0, 2.0], [2.0, 2.0]]
WALL = [[4.0, 0.0], [4.0, 1.5]]


@pytest.fixture
def robot():
    return FakeRobot()


@pytest.fixture
def guarded(robot, store):
    robot.zones = ZoneGuard(store, 0.135, 0.19)
    return robot


# -- what a zone may be ------------------------------------------------------------------------------

BAD = [
    ({"kind": "keepout", "polygon": [[0, 0], [1, 1], [1, 0], [0, 1]]}, "crosses itself"),
    ({"kind": "keepout", "polygon": [[0, 0], [1, 0]]}, "needs 3 to 100 points"),
    ({"kind": "keepout", "polygon": [[0, 0], [1, 0], [2, 0]]}, "covers 0.0000 m²"),
    ({"kind": "keepout", "polygon": [[0, 0], [1, 0], [1, 0], [0, 1]]}, "the same corner twice"),
    ({"kind": "keepout", "polygon": [[0, 0], [1, 0], [float("nan"), 1]]}, "polygon[2] must be [x, y]"),
    ({"kind": "keepout", "polygon": [[0, 0], [1, 0], [1e9, 1]]}, "polygon[2] must be [x, y]"),
    ({"kind": "keepout", "polygon": [[0, 0], [1, 0], [True, 1]]}, "polygon[2] must be [x, y]"),
    ({"kind": "keepout", "polygon": [[0, 0], [1, 0], [1, 1, 1]]}, "polygon[2] must be [x, y]"),
    ({"kind": "keepout", "polygon": [[i, i * i] for i in range(MAX_POINTS + 1)]}, "needs 3 to 100 points"),
    ({"kind": "keepout", "polygon": [[0, 0]] * 10000}, "needs 3 to 100 points"),
    ({"kind": "keepout", "line": WALL}, "has polygon, not line"),
    ({"kind": "wall", "line": [[0, 0], [0, 0.01]]}, "a wall is at least"),
    ({"kind": "wall", "line": [[0, 0], [0, 0], [1, 0]]}, "the same point twice"),
    ({"kind": "wall"}, "line must be a list"),
    ({"kind": "door", "line": WALL}, "kind must be"),
    ({"polygon": SQUARE}, "kind must be"),
    ({"kind": "keepout", "polygon": SQUARE, "enabled": "yes"}, "enabled must be true or false"),
    ({"kind": "keepout", "polygon": SQUARE, "colour": "red"}, "Unknown field \"colour\""),
    ([1, 2], "A zone is an object"),
]


@pytest.mark.parametrize("entry,why", BAD, ids=[why for _, why in BAD])
def test_a_bad_zone_says_what_is_wrong(entry, why):
    with pytest.raises(BadZone) as caught:
        make_zone("Katzenecke", entry)
    assert why in str(caught.value)


def test_names_follow_the_rule_of_every_name():
    assert make_zone("Ka\u0308tzchen", {"kind": "wall", "line": WALL}).name == "K\u00e4tzchen"  # kept in NFC
    for bad in ("", " ", "a/b", "a\nb", 5):
        with pytest.raises(BadZone):
            make_zone(bad, {"kind": "wall", "line": WALL})


def test_a_polygon_written_closed_is_the_same_polygon():
    closed = make_zone("a", {"kind": "keepout", "polygon": SQUARE + [SQUARE[0]]})
    assert closed.points == make_zone("a", {"kind": "keepout", "polygon": SQUARE}).points


def test_distance_is_zero_inside_and_a_wall_has_its_thickness():
    square = make_zone("a", {"kind": "keepout", "polygon": SQUARE})
    wall = make_zone("w", {"kind": "wall", "line": WALL})
    assert distance(square, 2.5, 1.5) == 0.0
    assert distance(square, 1.5, 1.5) == pytest.approx(0.5)
    assert distance(wall, 4.03, 1.0) == 0.0
    assert distance(wall, 4.25, 1.0) == pytest.approx(0.2)


# -- the mask ----------------------------------------------------------------------------------------

def _lethal(mask, width):
    return {(i % width, i // width) for i, v in enumerate(mask) if v == LETHAL}


def test_the_mask_holds_the_cells_whose_centres_lie_in_enabled_zones():
    square = make_zone("a", {"kind": "keepout", "polygon": SQUARE})
    off = make_zone("off", {"kind": "keepout", "polygon": [[0.2, 0.2], [0.8, 0.2], [0.8, 0.8]], "enabled": False})
    mask = cells([square, off], 100, 60, 0.05, 0.0, 0.0)
    assert set(mask) == {LETHAL, NO_OPINION}
    assert _lethal(mask, 100) == {(col, row) for col in range(40, 60) for row in range(20, 40)}


def test_a_wall_blocks_every_8_connected_step_across_it():
    diagonal = make_zone("w", {"kind": "wall", "line": [[0.5, 0.5], [2.5, 2.1]]})
    lethal = _lethal(cells([diagonal], 60, 60, 0.05, 0.0, 0.0), 60)

    def side(col, row):
        x, y = (col + 0.5) * 0.05, (row + 0.5) * 0.05
        return (2.1 - 0.5) * (x - 0.5) - (2.5 - 0.5) * (y - 0.5) > 0
    for col in range(12, 48):
        for row in range(12, 40):
            if (col, row) in lethal:
                continue
            for dc in (-1, 0, 1):
                for dr in (-1, 0, 1):
                    there = (col + dc, row + dr)
                    assert there in lethal or side(*there) == side(col, row), ((col, row), there)


def test_the_mask_follows_the_map_s_origin_and_rotation():
    square = make_zone("a", {"kind": "keepout", "polygon": SQUARE})
    shifted = cells([square], 100, 60, 0.05, -1.0, 0.5)
    assert min(_lethal(shifted, 100)) == (60, 10)
    turned = cells([square], 100, 100, 0.05, 5.0, 0.0, origin_yaw=math.pi / 2)  # the grid's x along the map's y
    assert min(_lethal(turned, 100)) == (20, 40) and max(_lethal(turned, 100)) == (39, 59)


def test_zones_the_robot_stands_in_are_left_out():
    square = make_zone("a", {"kind": "keepout", "polygon": SQUARE})
    assert set(cells([square], 100, 60, 0.05, 0.0, 0.0, skip={"a"})) == {NO_OPINION}


# -- kept in the waypoints file ------------------------------------------------------------------------

def test_zones_are_kept_beside_the_waypoints_and_the_seed_format_untouched_without(tmp_path):
    path = tmp_path / "w.yaml"
    seed = "waypoints:\n  kitchen: [1.0, 2.0, 0.0]\n"
    path.write_text(seed)
    store = WaypointStore(str(path))
    store.put_zone(make_zone("Katzenecke", {"kind": "keepout", "polygon": SQUARE}))
    store.put_zone(make_zone("Treppe oben", {"kind": "wall", "line": WALL, "enabled": False}))
    text = path.read_text()
    assert text == seed + ("zones:\n"
                           "  Katzenecke: {kind: keepout, polygon: [[2.0, 1.0], [3.0, 1.0], [3.0, 2.0], [2.0, 2.0]], "
                           "enabled: true}\n"
                           "  \"Treppe oben\": {kind: wall, line: [[4.0, 0.0], [4.0, 1.5]], enabled: false}\n")
    again = WaypointStore(str(path))
    assert [(z.name, z.enabled) for z in again.zones()] == [("Katzenecke", True), ("Treppe oben", False)]
    again.switch_zone("Treppe oben", True)
    again.delete_zone("Katzenecke")
    again.delete_zone("Treppe oben")
    assert path.read_text() == seed


@pytest.mark.parametrize("zones,why", [
    ("zones: [1, 2]", "'zones' must map names to zones"),
    ("zones:\n  a: {kind: keepout, polygon: [[0, 0], [1, 1], [1, 0], [0, 1]]}", "line 4: polygon crosses itself"),
    ("zones:\n  a: {kind: keepout, polygon: [[0, 0], [1, 0], [0, .nan]]}", "line 4: polygon[2] must be"),
    ("zones:\n  a: {kind: lava, line: [[0, 0], [1, 0]]}", "line 4: kind must be"),
])
def test_a_hand_edited_zone_that_cannot_be_kept_names_its_line_and_changes_nothing(tmp_path, zones, why):
    path = tmp_path / "w.yaml"
    path.write_text("waypoints:\n  kitchen: [1.0, 2.0, 0.0]\n" + zones + "\n")
    store = WaypointStore(str(path))
    assert why in store.problem
    with pytest.raises(WaypointFileError):
        store.put_zone(make_zone("b", {"kind": "wall", "line": WALL}))
    assert path.read_text().endswith(zones + "\n")


# -- the API -------------------------------------------------------------------------------------------

def test_put_patch_delete_a_zone_saved_before_it_is_answered(client, guarded, robot_config):
    path = robot_config.waypoints.file
    r = client.put("/zones/Katzenecke", json={"kind": "keepout", "polygon": SQUARE})
    assert r.status_code == 201 and r.get_json()["zone"] == {
        "name": "Katzenecke", "kind": "keepout", "polygon": SQUARE, "enabled": True, "waiting": False}
    assert "Katzenecke: {kind: keepout" in open(path, encoding="utf-8").read()
    assert client.put("/zones/Katzenecke", json={"kind": "keepout", "polygon": SQUARE}).status_code == 200
    r = client.patch("/zones/Katzenecke", json={"enabled": False})
    assert r.status_code == 200 and r.get_json()["zone"]["enabled"] is False
    assert "enabled: false" in open(path, encoding="utf-8").read()
    r = client.patch("/zones/Katzenecke", json={"name": "Napf"})
    assert r.status_code == 200 and r.get_json()["zone"]["name"] == "Napf"
    assert [z["name"] for z in client.get("/zones").get_json()["zones"]] == ["Napf"]
    assert client.delete("/zones/Napf").status_code == 204
    assert client.get("/zones").get_json() == {"zones": []}
    assert "zones:" not in open(path, encoding="utf-8").read()


@pytest.mark.parametrize("method,body,status,code", [
    ("put", {"kind": "keepout", "polygon": [[0, 0], [1, 1], [1, 0], [0, 1]]}, 400, "bad_zone"),
    ("put", {"kind": "keepout", "polygon": [[0, 0]] * 10000}, 413, "body_too_large"),
    ("put", {"kind": "keepout", "polygon": [[0, 0]] * 1000}, 400, "bad_zone"),
    ("put", {"kind": "wall", "line": [[0, 0], [1, "NaN"]]}, 400, "bad_zone"),
    ("put", {"kind": "wall"}, 400, "bad_zone"),
    ("put", {"kind": "wall", "line": WALL, "thickness": 2}, 400, "bad_request"),
    ("patch", {"enabled": "no"}, 404, "unknown_zone"),
    ("delete", None, 404, "unknown_zone"),
])
def test_bad_input_is_a_clear_error_and_nothing_is_written(client, guarded, robot_config, method, body, status, code):
    path = robot_config.waypoints.file
    before = open(path, encoding="utf-8").read()
    r = getattr(client, method)("/zones/Katzenecke", json=body)
    assert r.status_code == status and r.get_json()["error"] == code, r.get_json()
    assert open(path, encoding="utf-8").read() == before


def test_a_zone_over_the_dock_is_refused_the_robot_could_never_go_home(client, guarded, robot_config):
    before = open(robot_config.waypoints.file, encoding="utf-8").read()
    around_dock = [[-0.3, -0.3], [0.3, -0.3], [0.3, 0.3], [-0.3, 0.3]]  # the seed's dock stands at 0, 0
    r = client.put("/zones/Ecke", json={"kind": "keepout", "polygon": around_dock})
    assert r.status_code == 400 and "would cover the dock" in r.get_json()["message"]
    assert open(robot_config.waypoints.file, encoding="utf-8").read() == before
    off = {"kind": "keepout", "polygon": around_dock, "enabled": False}
    assert client.put("/zones/Ecke", json=off).status_code == 201
    r = client.patch("/zones/Ecke", json={"enabled": True})
    assert r.status_code == 400 and "would cover the dock" in r.get_json()["message"]


def test_a_goal_into_a_zone_is_refused_naming_it(guarded, store):
    from flask_move_server.core.errors import InZone
    from flask_move_server.core.geometry import Pose2D

    store.put_zone(make_zone("Katzenecke", {"kind": "keepout", "polygon": SQUARE}))
    with pytest.raises(InZone) as caught:
        guarded.zones.check(Pose2D(2.5, 1.5, 0.0), "Napf")
    assert "Napf" in str(caught.value) and "Katzenecke" in str(caught.value)
    with pytest.raises(InZone):
        guarded.zones.check(Pose2D(1.9, 1.5, 0.0))  # 10 cm off it: the robot's body would touch it
    guarded.zones.check(Pose2D(1.8, 1.5, 0.0))  # 20 cm off: free
    store.switch_zone("Katzenecke", False)
    guarded.zones.check(Pose2D(2.5, 1.5, 0.0))


def test_marking_a_place_inside_a_zone_keeps_it_and_warns(client, guarded):
    assert client.put("/zones/Katzenecke", json={"kind": "keepout", "polygon": SQUARE}).status_code == 201
    r = client.put("/waypoints/Napf", json={"x": 2.5, "y": 1.5, "yaw": 0.0})
    assert r.status_code == 201 and "Katzenecke" in r.get_json()["warning"]
    assert client.get("/waypoints/Napf").status_code == 200
    r = client.put("/waypoints/Flur", json={"x": 0.5, "y": 0.5, "yaw": 0.0})
    assert r.status_code == 201 and "warning" not in r.get_json()
