"""Occupancy maps in map_server's format: a PGM image and a YAML description.

The YAML keys are map_server's (``image``, ``resolution``, ``origin``,
``negate``, ``occupied_thresh``, ``free_thresh``, ``mode``) and a pixel becomes
a cell value the way map_server computes it: ``p = (255 - pixel) / 255``
(``pixel`` itself when ``negate``), above ``occupied_thresh`` → 100, below
``free_thresh`` → 0, otherwise -1 (unknown) in ``trinary`` mode, scaled to
1..99 in ``scale`` mode; ``raw`` keeps the pixel value. Row 0 of the image is
the top of the map, row 0 of the grid the bottom (``origin`` is the pose of
the lower-left cell), as in ``nav_msgs/OccupancyGrid``.

The YAML is read within bounds (:mod:`flask_move_server.config.guarded_yaml`: at most
:data:`MAX_YAML_BYTES`, no anchors or aliases, no deep nesting) and the image must lie in
the YAML's own folder (:func:`image_path`): a map file may be dropped in by anyone.

Pure: no rospy. A bad file raises ConfigError naming the file, key and a short reason
(a value is quoted by :func:`~flask_move_server.core.errors.shown`: at most 64 characters).
"""

import math
import os
import stat
from dataclasses import dataclass

from flask_move_server.config import guarded_yaml
from flask_move_server.core.errors import ConfigError, shown

OCCUPIED, FREE, UNKNOWN = 100, 0, -1
MAX_CELLS = 6000 * 6000  # past a gmapping canvas (4000 x 4000); a bigger image would not fit a Pi's memory
MODES = ("trinary", "scale", "raw")
MAX_YAML_BYTES = 64 * 1024  # map_saver writes ~150 bytes; room for notes, never megabytes to parse


@dataclass
class OccupancyMap:
    """A grid of cell values (-1 unknown, 0 free .. 100 occupied), bottom row first."""

    width: int
    height: int
    resolution: float
    origin_x: float
    origin_y: float
    cells: list
    source: str = "(map)"

    def cell_of(self, x, y):
        """The (column, row) holding the point (x, y) in the map frame, or None outside the map."""
        col = int(math.floor((x - self.origin_x) / self.resolution))
        row = int(math.floor((y - self.origin_y) / self.resolution))
        if 0 <= col < self.width and 0 <= row < self.height:
            return col, row
        return None

    def center_of(self, col, row):
        """The map-frame point at the centre of a cell."""
        return (self.origin_x + (col + 0.5) * self.resolution, self.origin_y + (row + 0.5) * self.resolution)

    def value_at(self, x, y):
        """The cell value under (x, y); None outside the map."""
        cell = self.cell_of(x, y)
        return None if cell is None else self.cells[cell[1] * self.width + cell[0]]

    def blocked(self):
        """A bytearray, 1 per cell the robot cannot enter: occupied (>= 50) or unknown."""
        return bytearray(1 if (v < 0 or v >= 50) else 0 for v in self.cells)


def load(yaml_path):
    """Read a map_server map (YAML + PGM) into an :class:`OccupancyMap`."""
    meta = read_meta(yaml_path)
    try:
        width, height, pixels = parse_pgm(read_image(image_path(yaml_path, meta["image"])))
    except OSError as exc:
        raise ConfigError(yaml_path, "image", "cannot read {}: {}".format(shown(meta["image"]), exc.strerror))
    except ValueError as exc:
        raise ConfigError(yaml_path, "image", "{}: {}".format(shown(meta["image"]), exc))
    cells = cells_from_pixels(width, height, pixels, meta)
    return OccupancyMap(width, height, meta["resolution"], meta["origin"][0], meta["origin"][1], cells,
                        source=str(yaml_path))


def read_meta(path, rotated_ok=False):
    """The checked keys of a map_server YAML; a rotated origin only when ``rotated_ok`` (the sim needs yaw 0)."""
    try:
        meta = guarded_yaml.read(path, MAX_YAML_BYTES)
    except OSError as exc:
        raise ConfigError(path, None, "cannot read the map: {}".format(exc.strerror))
    except guarded_yaml.Unreadable as exc:
        raise ConfigError(path, None, str(exc))
    if not isinstance(meta, dict):
        raise ConfigError(path, None, "a map_server map YAML must be a mapping (image:, resolution:, origin:, ...)")
    return _check_meta(path, meta, rotated_ok)


def _number(path, meta, key, default=None):
    value = meta.get(key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ConfigError(path, key, "must be a finite number, got {}".format(shown(value)))
    return float(value)


def _check_meta(path, meta, rotated_ok=False):
    for key in ("image", "resolution", "origin"):
        if key not in meta:
            raise ConfigError(path, key, "missing (map_server needs image, resolution and origin)")
    if not isinstance(meta["image"], str) or not meta["image"]:
        raise ConfigError(path, "image", "must be the image file name, got {}".format(shown(meta["image"])))
    origin = meta["origin"]
    if not isinstance(origin, list) or len(origin) != 3:
        raise ConfigError(path, "origin", "must be [x, y, yaw], got {}".format(shown(origin)))
    origin = [_number(path, {"origin": v}, "origin") for v in origin]
    if abs(origin[2]) > 1e-9 and not rotated_ok:
        raise ConfigError(path, "origin", "the simulator needs an unrotated map (yaw 0), got yaw {}".format(origin[2]))
    checked = {
        "image": meta["image"],
        "resolution": _number(path, meta, "resolution"),
        "origin": origin,
        "negate": meta.get("negate", 0),
        "occupied_thresh": _number(path, meta, "occupied_thresh", 0.65),
        "free_thresh": _number(path, meta, "free_thresh", 0.196),
        "mode": meta.get("mode", "trinary"),
    }
    if checked["resolution"] <= 0:
        raise ConfigError(path, "resolution", "must be greater than 0 (metres per cell)")
    if checked["negate"] not in (0, 1, True, False):
        raise ConfigError(path, "negate", "must be 0 or 1, got {}".format(shown(checked["negate"])))
    if checked["mode"] not in MODES:
        raise ConfigError(path, "mode", "must be one of {}, got {}".format(", ".join(MODES), shown(checked["mode"])))
    if not 0 <= checked["free_thresh"] < checked["occupied_thresh"] <= 1:
        raise ConfigError(path, "free_thresh", "thresholds must satisfy 0 <= free_thresh < occupied_thresh <= 1")
    return checked


def image_path(yaml_path, image):
    """The path of the map's ``image``, which must lie in the YAML's folder (symlinks followed).

    map_server reads any path; a map YAML dropped in by hand must not make the server
    open ``/etc/shadow`` or ``../../x.pgm``, so the image's real path must be inside the
    real folder of the YAML. ValueError says why not.
    """
    folder = os.path.dirname(os.path.abspath(yaml_path))
    path = os.path.join(folder, image)
    if not inside(folder, path):
        raise ValueError("outside the map's folder: put the image beside the YAML and name it there "
                         "(image: NAME.pgm)")
    return path


def inside(folder, path):
    """Whether ``path``, symlinks resolved, is in ``folder`` (itself resolved) or below it."""
    real_folder, real_path = os.path.realpath(folder), os.path.realpath(path)
    return real_path.startswith(real_folder.rstrip(os.sep) + os.sep)


def cells_from_pixels(width, height, pixels, meta):
    """map_server's pixel → cell rule, flipping rows so the grid's row 0 is the image's bottom row."""
    table = cell_table(meta)
    cells = []
    for row in range(height - 1, -1, -1):
        start = row * width
        cells.extend(table[p] for p in pixels[start:start + width])
    return cells


def cell_table(meta):
    """The cell value of each pixel value 0..255 under the YAML's negate, mode and thresholds."""
    negate, mode = bool(meta.get("negate", 0)), meta.get("mode", "trinary")
    occ_th, free_th = meta.get("occupied_thresh", 0.65), meta.get("free_thresh", 0.196)
    return [_cell_value(p, negate, mode, occ_th, free_th) for p in range(256)]


def _cell_value(pixel, negate, mode, occ_th, free_th):
    if mode == "raw":
        return pixel
    occ = (pixel if negate else 255 - pixel) / 255.0
    if occ > occ_th:
        return OCCUPIED
    if occ < free_th:
        return FREE
    if mode == "scale":
        return 1 + int(98 * (occ - free_th) / (occ_th - free_th))
    return UNKNOWN


def parse_pgm(data):
    """(width, height, pixels 0..255 top row first) of a binary (P5) or ASCII (P2) PGM."""
    magic = data[:2]
    width, height, maxval, pos = pgm_header(data)
    count = width * height
    if magic == b"P2":
        values = [int(v) for v in data[pos:].split()[:count]]
    elif maxval < 256:
        values = list(data[pos + 1:pos + 1 + count])
    else:
        raw = data[pos + 1:pos + 1 + 2 * count]
        values = [(raw[i] << 8) | raw[i + 1] for i in range(0, len(raw) - 1, 2)]
    if len(values) < count:
        raise ValueError("truncated PGM: {} of {} pixels".format(len(values), count))
    if maxval != 255:
        values = [min(255, v * 255 // maxval) for v in values]
    return width, height, values


def read_image(path, head_only=False):
    """The bytes of a map's PGM (only its first 4 KiB with ``head_only``), read within bounds.

    A map YAML is a file anyone may drop in or edit, so its ``image`` may name
    anything: a FIFO or a device (opened without blocking and refused, never a
    worker waiting or reading forever), or an image whose header declares more
    than :data:`MAX_CELLS` pixels (refused before its pixels are read). ValueError
    says which; OSError when it cannot be opened.
    """
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            raise ValueError("not a regular file; a map image must be a PGM file")
        head = f.read(4096)
        width, height, _, _ = pgm_header(head)
        if width * height > MAX_CELLS:
            raise ValueError("the image is {} x {} pixels, more than the {} cells a map may have".format(
                width, height, MAX_CELLS))
        if head_only:
            return head
        return head + f.read(8 * width * height)  # P2 text: a few digits and a space per pixel


def pgm_header(data):
    """(width, height, maxval, offset of the whitespace byte before the pixels) of a P5 or P2 PGM."""
    if data[:2] not in (b"P5", b"P2"):
        raise ValueError("not a PGM image (P5 or P2); convert it with e.g. `convert map.png map.pgm`")
    tokens, pos = _header_tokens(data, 3)
    width, height, maxval = tokens
    if width <= 0 or height <= 0 or not 0 < maxval < 65536:
        raise ValueError("bad PGM header {} x {}, maxval {}".format(width, height, maxval))
    return width, height, maxval, pos


def _header_tokens(data, wanted):
    """The first ``wanted`` integers after the magic number (comments skipped), and where they end."""
    tokens, pos, n = [], 2, len(data)
    while len(tokens) < wanted:
        while pos < n and data[pos:pos + 1].isspace():
            pos += 1
        if pos < n and data[pos:pos + 1] == b"#":
            while pos < n and data[pos:pos + 1] not in (b"\n", b"\r"):
                pos += 1
            continue
        start = pos
        while pos < n and data[pos:pos + 1].isdigit():
            pos += 1
        if start == pos:
            raise ValueError("bad PGM header")
        tokens.append(int(data[start:pos]))
    return tokens, pos


def write_pgm(path, width, height, pixels):
    """Write a binary PGM (P5, maxval 255), top row first, atomically enough for a generated file."""
    header = "P5\n# flask-move-server\n{} {}\n255\n".format(width, height).encode("ascii")
    with open(path, "wb") as f:
        f.write(header + bytes(pixels))
