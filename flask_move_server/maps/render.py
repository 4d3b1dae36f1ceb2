"""An occupancy grid as a PNG a phone page can show: grey like map_saver, cropped to what is known.

Free cells are white (254), occupied black (0), unknown grey (205), exactly
the pixels map_saver writes (:func:`mapfile.pixel_table`). The image is cropped
to the known cells plus a margin (1 m by default): a gmapping canvas is
4000 x 4000 cells of which a flat is a few hundred. Its top row is the map's
top. :class:`MapImage` carries what the page needs to turn a pixel into metres:
the resolution and the map-frame pose of the crop's lower-left corner.

Speed: no per-cell Python loop. The known area is found with ``bytes.lstrip`` /
``rstrip`` (over the whole buffer for the rows, per known row for the columns),
pixels come from ``bytes.translate``, the PNG from zlib. :class:`ImageCache`
keeps the last images by version so a repeat costs a dictionary look-up.
Pure: standard library only.
"""

import math
import struct
import threading
import zlib
from collections import OrderedDict
from dataclasses import dataclass

from flask_move_server.core.geometry import Pose2D, compose
from flask_move_server.maps.mapfile import UNKNOWN_PIXEL, cells_as_bytes, pixel_table

UNKNOWN_CELL = b"\xff"  # -1 as an int8 byte
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PIXELS = pixel_table()
_KNOWN = bytes(0 if byte == 0xFF else 1 for byte in range(256))  # translate: unknown → 0, known → 1


@dataclass(frozen=True)
class MapImage:
    """A rendered map: PNG bytes and the crop's geometry (pixels, metres per pixel, lower-left pose)."""

    png: bytes
    width: int
    height: int
    resolution: float
    origin_x: float
    origin_y: float
    origin_yaw: float
    empty: bool
    version: str

    def metadata(self):
        """What ``GET /map`` answers: the image's size and where its lower-left pixel is in the map frame."""
        return {"version": self.version, "resolution": self.resolution,
                "origin": [self.origin_x, self.origin_y, self.origin_yaw],
                "width": self.width, "height": self.height, "empty": self.empty}


def known_bounds(cells, width, height):
    """(first column, first row, last column, last row) of the cells that are not unknown; None if none is.

    Rows are compared whole with an unknown row (a memcmp each); only the band of
    known rows is translated to 0 (unknown) / 1 (known) and searched with find/rfind.
    """
    unknown_row = UNKNOWN_CELL * width
    first_row = next((row for row in range(height) if cells[row * width:(row + 1) * width] != unknown_row), None)
    if first_row is None:
        return None
    last_row = next(row for row in range(height - 1, first_row - 1, -1)
                    if cells[row * width:(row + 1) * width] != unknown_row)
    band = cells[first_row * width:(last_row + 1) * width].translate(_KNOWN)
    first_col, last_col = width, -1
    for start in range(0, len(band), width):
        left = band.find(b"\x01", start, start + width)
        if left >= 0:
            first_col = min(first_col, left - start)
            last_col = max(last_col, band.rfind(b"\x01", start, start + width) - start)
    return first_col, first_row, last_col, last_row


def crop_bounds(bounds, width, height, margin_cells):
    """``bounds`` grown by ``margin_cells`` on every side, kept inside the grid."""
    col0, row0, col1, row1 = bounds
    return (max(0, col0 - margin_cells), max(0, row0 - margin_cells),
            min(width - 1, col1 + margin_cells), min(height - 1, row1 + margin_cells))


def render(grid, margin=1.0, version=None):
    """The :class:`MapImage` of a grid (``width``, ``height``, ``resolution``, ``origin_x/y``, ``cells``)."""
    cells = cells_as_bytes(grid.cells)
    width, height, resolution = grid.width, grid.height, grid.resolution
    yaw = getattr(grid, "origin_yaw", 0.0)
    version = version if version is not None else grid_version(grid)
    bounds = known_bounds(cells, width, height)
    if bounds is None:
        png = encode_png(1, 1, bytes([UNKNOWN_PIXEL]))
        return MapImage(png, 1, 1, resolution, grid.origin_x, grid.origin_y, yaw, True, version)
    col0, row0, col1, row1 = crop_bounds(bounds, width, height, int(math.ceil(margin / resolution - 1e-9)))
    crop_width = col1 - col0 + 1
    rows = (cells[row * width + col0:row * width + col1 + 1] for row in range(row1, row0 - 1, -1))
    pixels = b"".join(rows).translate(_PIXELS)
    corner = compose(Pose2D(grid.origin_x, grid.origin_y, yaw), Pose2D(col0 * resolution, row0 * resolution, 0.0))
    x, y = corner.x, corner.y
    png = encode_png(crop_width, row1 - row0 + 1, pixels)
    return MapImage(png, crop_width, row1 - row0 + 1, resolution, x, y, yaw, False, version)


def encode_png(width, height, pixels, level=6):
    """An 8-bit greyscale PNG of ``pixels`` (``width`` x ``height`` bytes, top row first)."""
    scanlines = b"\x00" + b"\x00".join(pixels[row * width:(row + 1) * width] for row in range(height))
    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"".join((PNG_SIGNATURE, _chunk(b"IHDR", header),
                     _chunk(b"IDAT", zlib.compress(scanlines, level)), _chunk(b"IEND", b"")))


def _chunk(kind, data):
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def grid_version(grid):
    """A version string for a grid's content (adler32 of the cells, and its geometry), when none is given.

    Cheaper than a render (a few ms for 16 M cells); a caller that has a better
    one (the map message's sequence number, the file's mtime) passes that instead.
    """
    cells = cells_as_bytes(grid.cells)
    geometry = "{}x{}@{!r},{!r},{!r},{!r}".format(grid.width, grid.height, grid.resolution, grid.origin_x,
                                                  grid.origin_y, getattr(grid, "origin_yaw", 0.0))
    return "{:08x}{:08x}".format(zlib.adler32(cells), zlib.crc32(geometry.encode()) & 0xFFFFFFFF)


class ImageCache:
    """The last few rendered images, by version: a repeat request costs a look-up, not a render.

    One map is loaded and rendered at a time, across every cache: each can take ~80 MB for a
    gmapping canvas, so six workers asking at once for images not rendered yet (a page and its
    reloads, a script) would need six times that on a Pi. A request that waited for the render
    of the same version finds it cached.
    """

    _making = threading.Lock()  # class-wide: one make() at a time

    def __init__(self, size=4):
        self.size = size
        self._images = OrderedDict()
        self._lock = threading.Lock()

    def get(self, version):
        """The cached image of ``version``, or None (nothing is rendered)."""
        with self._lock:
            return self._images.get(version)

    def image(self, version, make):
        """The image of ``version``; ``make()`` renders it on a miss (one render at a time)."""
        image = self._cached(version)
        if image is not None:
            return image
        with ImageCache._making:
            image = self._cached(version)  # rendered by the request this one waited for
            if image is None:
                image = make()
                with self._lock:
                    self._images[version] = image
                    while len(self._images) > self.size:
                        self._images.popitem(last=False)
        return image

    def _cached(self, version):
        with self._lock:
            if version in self._images:
                self._images.move_to_end(version)
                return self._images[version]
        return None
