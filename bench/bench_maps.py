"""Benchmarks of the maps module: a map image of a gmapping canvas, and saving / loading a map.

    .venv/bin/python bench/bench_maps.py [--repeat 9]

The canvas is what gmapping publishes by default: 4000 x 4000 cells of 5 cm
(200 x 200 m), all unknown but a 30 x 20 m flat (600 x 400 cells) near the
middle: outer walls, four rooms with doors, furniture blocks, and a ragged edge
of unknown where the laser did not reach. Targets (issue 12): first render
<= 150 ms, a repeat <= 5 ms.

The live path (``GET /map/image`` while mapping) is measured too: the
canvas as an OccupancyGrid's wire bytes (what rospy.AnyMsg hands over),
decoded by ``maps.wire`` versus genpy's ``deserialize`` (the int tuple), and
MapService's first render and its repeat (the ETag check a 304 costs).

Prints a markdown table (docs/performance.md, section Maps).
"""

import argparse
import os
import random
import shutil
import statistics
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from flask_move_server.maps import mapfile, render  # noqa: E402
from flask_move_server.maps.catalogue import MapCatalogue  # noqa: E402
from flask_move_server.maps.service import MapService  # noqa: E402
from flask_move_server.maps.wire import decode  # noqa: E402
from flask_move_server.waypoints.store import WaypointStore  # noqa: E402

SIZE, RESOLUTION = 4000, 0.05
FLAT_COL, FLAT_ROW, FLAT_W, FLAT_H = 1900, 1850, 600, 400
FREE, WALL = b"\x00", b"\x64"


def canvas():
    """The 4000 x 4000 int8 cells: unknown, and the mapped flat (built row by row, not cell by cell)."""
    rng = random.Random(12)
    cells = bytearray(b"\xff" * (SIZE * SIZE))
    for r in range(FLAT_H):
        row = bytearray(FREE * FLAT_W)
        if r in (0, FLAT_H - 1, FLAT_H // 2) and not (FLAT_H // 2 == r and 100 < rng.randrange(600) < 140):
            row[:] = WALL * FLAT_W
        row[0:1] = row[-1:] = row[FLAT_W // 3:FLAT_W // 3 + 1] = WALL
        if r % 97 < 30:  # furniture along the rooms
            row[200:240] = WALL * 40
        ragged = rng.randrange(0, 15)  # the laser's shadow at the edges: unknown
        row[FLAT_W - ragged:] = b"\xff" * ragged
        start = (FLAT_ROW + r) * SIZE + FLAT_COL
        cells[start:start + FLAT_W] = row
    return bytes(cells)


def timed(action, repeat):
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        result = action()
        times.append((time.perf_counter() - t) * 1e3)
    return statistics.median(times), max(times), result


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args(argv)
    grid = mapfile.Grid(SIZE, SIZE, RESOLUTION, -100.0, -100.0, canvas())
    rows = []

    med, top, image = timed(lambda: render.render(grid, version="seq-1"), args.repeat)
    rows.append(("first render (version given: the map message's seq)", med, top))
    med, top, _ = timed(lambda: render.render(grid), args.repeat)
    rows.append(("first render, version computed (adler32 of the cells)", med, top))
    med, top, _ = timed(lambda: render.grid_version(grid), args.repeat)
    rows.append(("grid_version alone", med, top))
    cache = render.ImageCache()
    cache.image("seq-1", lambda: image)
    med, top, _ = timed(lambda: cache.image("seq-1", lambda: render.render(grid)), args.repeat)
    rows.append(("repeat (ImageCache hit)", med, top))
    as_tuple = tuple(b - 256 if b > 127 else b for b in grid.cells[:SIZE * 500])
    med, top, _ = timed(lambda: mapfile.cells_as_bytes(as_tuple), 3)
    rows.append(("int8 tuple -> bytes, per 1 M cells (rospy's OccupancyGrid.data)", med / 2.0, top / 2.0))

    rows.extend(live_rows(grid, args.repeat))

    with tempfile.TemporaryDirectory() as folder:
        maps = MapCatalogue(folder)
        med, top, _ = timed(lambda: maps.save("flat", grid, overwrite=True), max(3, args.repeat // 3))
        rows.append(("save the canvas (16 MB pgm + yaml, fsynced)", med, top))
        med, top, _ = timed(lambda: maps.load("flat"), max(3, args.repeat // 3))
        rows.append(("load it back (map_server rules)", med, top))
        med, top, _ = timed(maps.list, args.repeat)
        rows.append(("list the folder (1 map)", med, top))

    print("| measure | median ms | max ms |")
    print("|---|---:|---:|")
    for label, med, top in rows:
        print("| {} | {:.3f} | {:.3f} |".format(label, med, top))
    print()
    print("image: {} x {} px, PNG {} bytes, crop origin ({:.2f}, {:.2f})".format(
        image.width, image.height, len(image.png), image.origin_x, image.origin_y))


def wire_bytes(grid):
    """The canvas as a serialized nav_msgs/OccupancyGrid (genpy), as the map topic carries it."""
    import io
    from array import array

    from nav_msgs.msg import OccupancyGrid

    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    msg.info.resolution = grid.resolution
    msg.info.width, msg.info.height = grid.width, grid.height
    msg.info.origin.position.x, msg.info.origin.position.y = grid.origin_x, grid.origin_y
    msg.info.origin.orientation.w = 1.0
    msg.data = array("b", grid.cells)
    buff = io.BytesIO()
    msg.serialize(buff)
    return buff.getvalue()


class LiveMap:
    """A map source holding wire bytes and decoding them on demand, as ros/map_source.MapSource does."""

    def __init__(self, raw):
        self.raw, self.version, self.context = raw, 1, {"mode": "mapping", "map": None}

    def held_version(self):
        return self.version

    def current(self):
        return self.version, decode(self.raw)[1]


def live_rows(grid, repeat):
    """The live map: decode (ours vs genpy), MapService's first image and its repeat."""
    from nav_msgs.msg import OccupancyGrid

    raw = wire_bytes(grid)
    rows = []
    med, top, _ = timed(lambda: decode(raw), repeat)
    rows.append(("decode the map message's wire bytes (maps.wire)", med, top))
    med, top, _ = timed(lambda: OccupancyGrid().deserialize(raw), 3)
    rows.append(("genpy OccupancyGrid.deserialize, for comparison (int tuple)", med, top))

    folder = tempfile.mkdtemp(prefix="bench-maps-")  # the server's own layout: maps/ beside the waypoints
    store = WaypointStore(os.path.join(folder, "waypoints.yaml"))

    def first_image():
        service = MapService(MapCatalogue(os.path.join(folder, "maps")), store, LiveMap(raw))
        return service, service.live_image()

    med, top, (service, _) = timed(first_image, repeat)
    rows.append(("GET /map/image, first: decode + render", med, top))
    med, top, _ = timed(service.live_image, repeat)
    rows.append(("GET /map/image, repeat (cached by version)", med, top))
    med, top, _ = timed(service.live_etag, repeat)
    rows.append(("GET /map/image with If-None-Match: the ETag check (304)", med, top))
    shutil.rmtree(folder, ignore_errors=True)
    return rows


if __name__ == "__main__":
    main()
