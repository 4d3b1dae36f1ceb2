"""The maps folder, map_saver's file pair and map images (flask_move_server.maps): pure, no ROS."""

import math
import os
import struct
import zlib

import pytest
import yaml

from flask_move_server.core.errors import BadMapName, MapExists, MapFileError, MapInUse, UnknownMap
from flask_move_server.maps import mapfile, render
from flask_move_server.maps.catalogue import MapCatalogue, check_map_name
from flask_move_server.maps.mapfile import Grid
from flask_move_server.sim import occupancy
from flask_move_server.waypoints import make_waypoint
from flask_move_server.waypoints.store import WaypointStore

# One cell of every kind map_saver tells apart, and what it folds each into.
VALUES = [-1, 0, 10, 25, 26, 50, 64, 65, 100, 127, -128, -5]
FOLDED = [-1, 0, 0, 0, -1, -1, -1, 100, 100, 100, -1, -1]


def small_grid(values=VALUES, width=4, **kw):
    """A grid of ``values`` (bottom row first), ``width`` cells wide, 5 cm cells, origin (-1, -2)."""
    return Grid(width, len(values) // width, 0.05, -1.0, -2.0, values, **kw)


def int8(cells):
    return [b - 256 if b > 127 else b for b in cells]


@pytest.fixture
def maps(tmp_path):
    return MapCatalogue(str(tmp_path / "maps"))


def put_waypoint(maps, map_name, name="dock", x=1.0, y=2.0):
    WaypointStore(maps.waypoints_path(map_name)).put(make_waypoint(name, x, y, 0.0))


# map_saver's pair ---------------------------------------------------------------------------


def test_a_saved_map_reads_back_as_map_saver_folds_it(maps):
    maps.save("flat", small_grid())
    grid = maps.load("flat")
    assert (grid.width, grid.height, grid.resolution, grid.origin_x, grid.origin_y) == (4, 3, 0.05, -1.0, -2.0)
    assert int8(grid.cells) == FOLDED


def test_the_files_are_the_ones_map_saver_writes(maps):
    maps.save("flat", small_grid())
    with open(os.path.join(maps.folder, "flat.pgm"), "rb") as f:
        pgm = f.read()
    header = b"P5\n# CREATOR: map_saver.cpp 0.050 m/pix\n4 3\n255\n"
    assert pgm.startswith(header)
    # The image's top row is the grid's top (last) row: 100, 127, -128, -5 → 0, 0, 205, 205.
    assert list(pgm[len(header):]) == [0, 0, 205, 205, 205, 205, 205, 0, 205, 254, 254, 254]
    with open(maps.yaml_path("flat"), encoding="utf-8") as f:
        assert f.read() == ("image: flat.pgm\nresolution: 0.050000\norigin: [-1.000000, -2.000000, 0.000000]\n"
                            "negate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n\n")


def test_map_server_rules_read_the_saved_pair_as_the_same_trinary_grid(maps):
    maps.save("flat", small_grid())
    by_map_server = occupancy.load(maps.yaml_path("flat"))
    assert by_map_server.cells == FOLDED == int8(maps.load("flat").cells)


def test_a_map_made_elsewhere_in_ascii_pgm_is_read_by_map_servers_rules(maps, tmp_path):
    os.makedirs(maps.folder)
    with open(os.path.join(maps.folder, "old.pgm"), "w") as f:
        f.write("P2\n2 2\n255\n0 254\n205 254\n")
    with open(os.path.join(maps.folder, "old.yaml"), "w") as f:
        f.write("image: old.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n")
    assert int8(maps.load("old").cells) == [-1, 0, 100, 0]


def test_a_grid_given_as_a_list_or_as_raw_bytes_is_the_same_grid():
    raw = bytes(v & 0xFF for v in VALUES)
    assert small_grid().cells == small_grid(raw).cells == small_grid(bytearray(raw)).cells


# atomic saving ------------------------------------------------------------------------------


def test_a_save_that_fails_half_way_leaves_no_map_and_no_half_file(maps, monkeypatch):
    real_rename = os.rename

    def rename(src, dst):
        if dst.endswith(".yaml"):
            raise OSError(28, "No space left on device")
        real_rename(src, dst)

    monkeypatch.setattr(os, "rename", rename)
    monkeypatch.setattr(os, "replace", rename)
    with pytest.raises(MapFileError, match="No space left"):
        maps.save("flat", small_grid())
    assert maps.list() == [] and not maps.exists("flat")
    assert not os.path.exists(maps.yaml_path("flat"))
    assert maps.leftovers() == []


def test_a_write_that_raises_leaves_nothing_under_the_final_names(maps, monkeypatch):
    def broken(*args):
        raise OSError(5, "Input/output error")

    monkeypatch.setattr(os, "fsync", broken)
    with pytest.raises(MapFileError):
        maps.save("flat", small_grid())
    assert sorted(os.listdir(maps.folder)) == []


def test_a_folder_that_refuses_new_files_refuses_the_save_cleanly(maps, monkeypatch):
    import tempfile

    def refused(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(tempfile, "mkstemp", refused)
    with pytest.raises(MapFileError, match="Permission denied"):
        maps.save("flat", small_grid())
    assert maps.list() == []


def test_leftovers_of_a_killed_save_are_not_listed_and_removed_on_request(maps):
    maps.save("flat", small_grid())
    part = mapfile.write_part(maps.folder, "kitchen", ".pgm", b"P5\n")
    with open(os.path.join(maps.folder, "kitchen.pgm"), "wb") as f:  # renamed in, its YAML never was
        f.write(mapfile.pgm_bytes(small_grid()))
    assert [m.name for m in maps.list()] == ["flat"]
    assert maps.leftovers() == [part]
    assert maps.remove_leftovers() == [part]
    assert not os.path.exists(part) and maps.exists("flat")


def test_an_existing_name_is_refused_unless_overwrite_is_asked(maps):
    maps.save("flat", small_grid())
    put_waypoint(maps, "flat")
    with pytest.raises(MapExists, match="flat"):
        maps.save("flat", small_grid([0] * 8))
    assert int8(maps.load("flat").cells) == FOLDED
    maps.save("flat", small_grid([0] * 8), overwrite=True)
    assert int8(maps.load("flat").cells) == [0] * 8
    assert maps.describe("flat").waypoints == 1  # the map's waypoints stay with it


# the catalogue ------------------------------------------------------------------------------


def test_the_list_says_what_a_page_shows_of_each_map(maps):
    maps.save("flat", small_grid())
    maps.save("garage", small_grid([0] * 6, width=3))
    put_waypoint(maps, "flat", "dock")
    put_waypoint(maps, "flat", "kitchen")
    listed = [m.as_dict() for m in maps.list()]
    assert [m["name"] for m in listed] == ["flat", "garage"]
    flat = listed[0]
    assert (flat["width"], flat["height"], flat["resolution"], flat["origin"]) == (4, 3, 0.05, [-1.0, -2.0, 0.0])
    assert flat["waypoints"] == 2 and listed[1]["waypoints"] == 0
    assert flat["modified"].endswith("+00:00") and flat["modified"][:4].isdigit()


def test_a_missing_folder_lists_no_maps(maps):
    assert maps.list() == []


def test_an_unknown_map_is_named_with_close_names(maps):
    maps.save("kitchen", small_grid())
    with pytest.raises(UnknownMap, match="kitchn.*kitchen"):
        maps.describe("kitchn")


def test_rename_moves_the_image_and_the_waypoints(maps):
    maps.save("flat", small_grid())
    put_waypoint(maps, "flat")
    info = maps.rename("flat", "home")
    assert [m.name for m in maps.list()] == ["home"] and info.waypoints == 1
    assert int8(maps.load("home").cells) == FOLDED
    assert sorted(os.listdir(maps.folder)) == ["home.pgm", "home.waypoints.yaml", "home.yaml"]
    with open(maps.yaml_path("home")) as f:
        assert yaml.safe_load(f)["image"] == "home.pgm"


def test_rename_refuses_the_active_map_an_existing_name_and_an_unknown_one(maps):
    maps.save("flat", small_grid())
    maps.save("home", small_grid())
    with pytest.raises(MapInUse):
        maps.rename("flat", "new", active="flat")
    with pytest.raises(MapExists):
        maps.rename("flat", "home")
    with pytest.raises(UnknownMap):
        maps.rename("nowhere", "new")
    assert [m.name for m in maps.list()] == ["flat", "home"]


def test_delete_removes_the_map_and_its_waypoints_but_never_the_active_one(maps):
    maps.save("flat", small_grid())
    maps.save("home", small_grid())
    put_waypoint(maps, "flat")
    with pytest.raises(MapInUse, match="in use"):
        maps.delete("home", active="home")
    maps.delete("flat", active="home")
    assert [m.name for m in maps.list()] == ["home"]
    assert sorted(os.listdir(maps.folder)) == ["home.pgm", "home.yaml"]
    with pytest.raises(UnknownMap):
        maps.delete("flat")


@pytest.mark.parametrize("name", ["../etc/passwd", "a/b", "..", ".", ".hidden", "flat.waypoints", "", " flat",
                                  "x" * 65, "flat~", "nul\0", None])
def test_names_that_are_not_a_safe_file_name_are_refused(maps, name):
    with pytest.raises(BadMapName):
        check_map_name(name)
    with pytest.raises(BadMapName):
        maps.save(name, small_grid())
    assert not os.path.exists(maps.folder) or os.listdir(maps.folder) == []


def test_names_like_waypoint_names_are_fine_even_those_yaml_would_misread(maps):
    names = ["- odd", "flat 2", "lab_B-1", "v1.2", "yes"]
    for name in names:
        maps.save(name, small_grid())
    assert [m.name for m in maps.list()] == names
    for name in names:  # map_server finds each image by the YAML's image key
        assert occupancy.load(maps.yaml_path(name)).cells == FOLDED


def test_a_broken_map_is_listed_with_its_problem_and_can_be_deleted(maps):
    maps.save("flat", small_grid())
    os.unlink(os.path.join(maps.folder, "flat.pgm"))
    (info,) = maps.list()
    assert info.width is None and "flat.pgm" in info.as_dict()["problem"]
    with pytest.raises(MapFileError, match="flat"):
        maps.load("flat")
    maps.delete("flat")
    assert maps.list() == []


def test_cells_out_of_int8_or_a_bad_resolution_are_refused():
    with pytest.raises(ValueError, match="int8"):
        small_grid([200] * 8)
    with pytest.raises(ValueError, match="resolution"):
        Grid(1, 1, 0.0, 0.0, 0.0, [0])


# images -------------------------------------------------------------------------------------


def decode_png(data):
    """(width, height, rows of pixel values top first) of an 8-bit greyscale PNG, checking every CRC."""
    assert data[:8] == render.PNG_SIGNATURE
    pos, chunks = 8, {}
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        assert struct.unpack(">I", data[pos + 8 + length:pos + 12 + length])[0] == zlib.crc32(kind + body)
        chunks[kind] = chunks.get(kind, b"") + body
        pos += 12 + length
    width, height, depth, colour = struct.unpack(">IIBB", chunks[b"IHDR"][:10])
    assert (depth, colour) == (8, 0) and b"IEND" in chunks
    raw = zlib.decompress(chunks[b"IDAT"])
    rows = [raw[r * (width + 1):(r + 1) * (width + 1)] for r in range(height)]
    assert all(row[0] == 0 for row in rows)
    return width, height, [list(row[1:]) for row in rows]


def room_grid():
    """200 x 100 cells of 10 cm, origin (-5, -2): unknown but a free room (columns 50..69, rows 30..39)
    with one occupied cell at column 60, row 35."""
    width, height = 200, 100
    cells = bytearray(b"\xff" * (width * height))
    for row in range(30, 40):
        cells[row * width + 50:row * width + 70] = bytes(20)
    cells[35 * width + 60] = 100
    return Grid(width, height, 0.1, -5.0, -2.0, bytes(cells))


def test_the_image_is_cropped_to_the_known_area_plus_a_metre():
    image = render.render(room_grid(), margin=1.0)
    # Known columns 50..69, rows 30..39, grown by 10 cells: columns 40..79, rows 20..49.
    assert (image.width, image.height, image.empty) == (40, 30, False)
    assert image.metadata()["origin"] == pytest.approx([-5.0 + 4.0, -2.0 + 2.0, 0.0])
    assert image.metadata()["resolution"] == 0.1


def test_a_known_place_lands_on_the_right_pixels():
    image = render.render(room_grid(), margin=1.0)
    width, height, rows = decode_png(image.png)
    assert (width, height) == (image.width, image.height)

    def pixel_at(x, y):  # a page's formula: metres → pixel, row 0 at the top
        col = int((x - image.origin_x) / image.resolution)
        return rows[image.height - 1 - int((y - image.origin_y) / image.resolution)][col]

    assert pixel_at(-5.0 + 60.5 * 0.1, -2.0 + 35.5 * 0.1) == 0  # the occupied cell: black
    assert pixel_at(-5.0 + 50.5 * 0.1, -2.0 + 30.5 * 0.1) == 254  # a corner of the room: white
    assert pixel_at(-5.0 + 69.5 * 0.1, -2.0 + 39.5 * 0.1) == 254
    assert rows[0][0] == rows[-1][-1] == 205  # the margin: unknown grey
    assert sum(row.count(254) for row in rows) == 199 and sum(row.count(0) for row in rows) == 1


def test_the_margin_stops_at_the_edge_of_the_grid():
    grid = Grid(3, 2, 0.5, 0.0, 0.0, [0, -1, -1, -1, -1, 100])
    image = render.render(grid, margin=10.0)
    assert (image.width, image.height, image.origin_x, image.origin_y) == (3, 2, 0.0, 0.0)
    assert decode_png(image.png)[2] == [[205, 205, 0], [254, 205, 205]]


def test_the_crop_origin_of_a_rotated_map_turns_with_it():
    grid = room_grid()
    turned = Grid(grid.width, grid.height, 0.1, 1.0, 2.0, grid.cells, origin_yaw=math.pi / 2)
    image = render.render(turned, margin=1.0)
    # The crop starts 4 m along the grid's x axis (the map's +y) and 2 m along its y (the map's -x).
    assert image.metadata()["origin"] == pytest.approx([1.0 - 2.0, 2.0 + 4.0, math.pi / 2])


def test_an_all_unknown_map_gives_a_small_valid_image_and_says_it_is_empty():
    grid = Grid(400, 300, 0.05, -10.0, -7.5, b"\xff" * 120000)
    image = render.render(grid)
    assert image.empty and image.metadata()["empty"] is True
    assert decode_png(image.png) == (1, 1, [[205]])
    assert len(image.png) < 100


def test_a_repeat_of_the_same_version_is_not_rendered_again():
    cache, renders = render.ImageCache(size=2), []

    def make(grid):
        renders.append(1)
        return render.render(grid)

    grid = room_grid()
    version = render.grid_version(grid)
    first = cache.image(version, lambda: make(grid))
    assert cache.image(version, lambda: make(grid)) is first and len(renders) == 1
    changed = Grid(grid.width, grid.height, grid.resolution, grid.origin_x, grid.origin_y, b"\x00" + grid.cells[1:])
    assert render.grid_version(changed) != version
    cache.image(render.grid_version(changed), lambda: make(changed))
    assert len(renders) == 2


def test_a_stored_maps_version_changes_when_it_is_saved_again(maps):
    maps.save("flat", small_grid())
    before = maps.version("flat")
    assert maps.version("flat") == before
    maps.save("flat", small_grid([0] * 8), overwrite=True)
    assert maps.version("flat") != before
