"""A map on disk as map_saver writes it: ``NAME.pgm`` (binary P5) and ``NAME.yaml``.

Writing follows map_server's ``map_saver.cpp`` (noetic): every cell of the
``nav_msgs/OccupancyGrid`` becomes one pixel, top image row = top of the map;
a cell 0..``free`` (25) is 254, a cell >= ``occupied`` (65) is 0, anything else
(unknown -1, the doubtful middle) is 205. The YAML is map_saver's text, with its
fixed ``negate: 0``, ``occupied_thresh: 0.65``, ``free_thresh: 0.196``, so a map
saved here and one saved by ``rosrun map_server map_saver`` are interchangeable.

Saving keeps one complete version of the pair on disk at every moment (see
:func:`save`): files are written under temporary names in the folder
(``.~NAME.*.part``), fsynced, and the YAML is replaced in one rename by a YAML
naming an image already in place, so a save killed at any step leaves the old
map or the new one, never neither, and a new map is listed only once complete.

Reading uses map_server's rules from :mod:`flask_move_server.sim.occupancy`
(one place), with a C-speed path for the 8-bit P5 images map_saver writes.
Cells are ``bytes`` of signed int8, bottom row first, as OccupancyGrid's payload.
Pure: no rospy.
"""

import array
import json
import math
import os
import tempfile
import uuid
from dataclasses import dataclass

import yaml

from flask_move_server.core.errors import ConfigError, MapExists, MapFileError, shown
from flask_move_server.sim import occupancy
from flask_move_server.waypoints.locked_file import fsync_dir, new_file_mode

FREE_PIXEL, OCCUPIED_PIXEL, UNKNOWN_PIXEL = 254, 0, 205
MAP_SAVER_FREE, MAP_SAVER_OCCUPIED = 25, 65  # map_saver's --free / --occ defaults
LEFTOVER_PREFIX, LEFTOVER_SUFFIX = ".~", ".part"


@dataclass
class Grid:
    """An occupancy grid: ``cells`` int8 bytes (-1 unknown, 0 free .. 100 occupied), bottom row first."""

    width: int
    height: int
    resolution: float
    origin_x: float
    origin_y: float
    cells: bytes
    origin_yaw: float = 0.0

    def __post_init__(self):
        if not (self.resolution > 0 and math.isfinite(self.resolution)):
            raise ValueError("a grid's resolution must be a positive number of metres, got {!r}".format(
                self.resolution))
        self.cells = cells_as_bytes(self.cells)
        if len(self.cells) != self.width * self.height:
            raise ValueError("a {} x {} grid needs {} cells, got {}".format(
                self.width, self.height, self.width * self.height, len(self.cells)))

    def value(self, col, row):
        """The cell value (-128..127) at a column and row (row 0 at the bottom)."""
        byte = self.cells[row * self.width + col]
        return byte - 256 if byte > 127 else byte


def cells_as_bytes(cells):
    """OccupancyGrid cells as int8 ``bytes``: raw bytes pass through, ints -128..127 are packed."""
    if isinstance(cells, bytes):
        return cells
    if isinstance(cells, (bytearray, memoryview)):
        return bytes(cells)
    try:
        return array.array("b", cells).tobytes()
    except OverflowError:
        raise ValueError("occupancy cells are int8 values, -128..127 (-1 unknown, 0..100)") from None


def pixel_table(free=MAP_SAVER_FREE, occupied=MAP_SAVER_OCCUPIED):
    """For each int8 cell byte 0..255, the grey pixel map_saver writes (a ``bytes.translate`` table)."""
    def grey(byte):
        value = byte - 256 if byte > 127 else byte
        if 0 <= value <= free:
            return FREE_PIXEL
        return OCCUPIED_PIXEL if value >= occupied else UNKNOWN_PIXEL
    return bytes(grey(b) for b in range(256))


def flipped_rows(data, width, height):
    """The rows of ``data`` in the other order (grid bottom-first ↔ image top-first), C-speed slices."""
    return b"".join(data[row * width:(row + 1) * width] for row in range(height - 1, -1, -1))


def pgm_bytes(grid, free=MAP_SAVER_FREE, occupied=MAP_SAVER_OCCUPIED):
    """The P5 PGM map_saver writes for ``grid`` (header comment included)."""
    header = "P5\n# CREATOR: map_saver.cpp {:.3f} m/pix\n{} {}\n255\n".format(
        grid.resolution, grid.width, grid.height).encode("ascii")
    pixels = grid.cells.translate(pixel_table(free, occupied))
    return header + flipped_rows(pixels, grid.width, grid.height)


def yaml_text(image, resolution, origin, extra=None):
    """map_saver's YAML text (``%f`` numbers, its fixed thresholds); ``extra`` keys appended."""
    text = "image: {}\nresolution: {:f}\norigin: [{:f}, {:f}, {:f}]\nnegate: 0\n" \
           "occupied_thresh: 0.65\nfree_thresh: 0.196\n\n".format(
               _yaml_scalar(image), resolution, origin[0], origin[1], origin[2])
    if extra:
        text += yaml.safe_dump(dict(extra), default_flow_style=False, sort_keys=False)
    return text


def _yaml_scalar(text):
    """``text`` plain as map_saver prints it, quoted only when YAML would read it as something else."""
    try:
        if yaml.safe_load("k: " + text) == {"k": text}:
            return text
    except yaml.YAMLError:
        pass
    return json.dumps(text, ensure_ascii=False)  # a name in any language stays readable


def save(folder, name, grid, overwrite=False):
    """Write ``NAME.pgm`` + ``NAME.yaml`` into ``folder`` atomically; MapExists if saved and not ``overwrite``.

    At every moment one complete version of the map is on disk, old or new: the YAML is only
    ever replaced (``os.replace``) by one naming an image already written and fsynced, and an
    image is only replaced once no YAML names it. Overwriting a map whose YAML names
    ``NAME.pgm`` therefore goes through the new image's temporary name: the YAML names it,
    then ``NAME.pgm`` is replaced (from a hard link, or a second copy where the folder has none),
    then the YAML names ``NAME.pgm`` again. The start-up cleanup
    (:meth:`~flask_move_server.maps.catalogue.MapCatalogue.leftovers`) keeps a temporary a YAML names.
    """
    folder = os.path.abspath(folder)
    yaml_path = os.path.join(folder, name + ".yaml")
    if not overwrite and os.path.exists(yaml_path):
        raise MapExists("A map named {!r} is already saved; ask to overwrite it, or pick another name.".format(name))
    old_image, pgm_path = named_image(yaml_path), os.path.join(folder, name + ".pgm")
    part = None
    try:
        data = pgm_bytes(grid)
        part = write_part(folder, name, ".pgm", data)
        if same_file(old_image, pgm_path):
            _put_yaml(folder, name, os.path.basename(part), grid)  # the new version, under the part's name
            os.replace(_second_copy(folder, name, part, data), pgm_path)
        else:  # no YAML names NAME.pgm: it can be replaced at once
            os.replace(part, pgm_path)
        fsync_dir(folder)
        _put_yaml(folder, name, name + ".pgm", grid)
        for stale in (part, old_image):  # and an image an interrupted save left named
            if stale and is_part(stale, name):
                _remove_quietly(stale)
    except OSError as exc:
        if part is not None and not same_file(named_image(yaml_path), part):
            _remove_quietly(part)
        raise MapFileError("Could not save the map {!r} in {}: {}.".format(
            name, folder, exc.strerror or exc)) from exc
    return yaml_path


def _second_copy(folder, name, part, data):
    """Another temporary name for the image ``part``: a hard link, or (FAT, exFAT: none) a second copy."""
    link = os.path.join(folder, "{}{}.{}.pgm{}".format(LEFTOVER_PREFIX, name, uuid.uuid4().hex[:8], LEFTOVER_SUFFIX))
    try:
        os.link(part, link)
        return link
    except OSError:
        return write_part(folder, name, ".pgm", data)


def _put_yaml(folder, name, image, grid):
    """``NAME.yaml`` replaced, in one rename, by map_saver's YAML naming ``image``."""
    origin = (grid.origin_x, grid.origin_y, grid.origin_yaw)
    part = write_part(folder, name, ".yaml", yaml_text(image, grid.resolution, origin).encode())
    try:
        os.replace(part, os.path.join(folder, name + ".yaml"))
    except BaseException:
        _remove_quietly(part)
        raise
    fsync_dir(folder)


def named_image(yaml_path):
    """The path of the image the map YAML at ``yaml_path`` names now (None: no YAML, or it cannot say)."""
    try:
        meta = occupancy.read_meta(yaml_path, rotated_ok=True)
        return occupancy.image_path(yaml_path, meta["image"])
    except (ConfigError, ValueError):
        return None


def same_file(a, b):
    """Whether the paths ``a`` and ``b`` (None: no file) name the same file, links resolved."""
    return a is not None and b is not None and os.path.realpath(a) == os.path.realpath(b)


def is_part(path, name=None):
    """Whether ``path`` is named as a save's temporary file (``.~NAME.*.part``; of map ``name`` if given)."""
    base = os.path.basename(path)
    prefix = LEFTOVER_PREFIX + (name + "." if name is not None else "")
    return base.startswith(prefix) and base.endswith(LEFTOVER_SUFFIX)


def write_part(folder, name, suffix, data):
    """``data`` in a new temporary file of ``folder``, flushed to the disk; returns its path."""
    fd, path = tempfile.mkstemp(prefix="{}{}.".format(LEFTOVER_PREFIX, name),
                                suffix=suffix + LEFTOVER_SUFFIX, dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            os.fchmod(f.fileno(), new_file_mode())  # mkstemp's 0o600 would hide the map from other accounts
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
    except BaseException:
        _remove_quietly(path)
        raise
    return path


def _remove_quietly(path):
    try:
        os.unlink(path)
    except OSError:
        pass


def load(yaml_path):
    """Read a map_server map (any image map_server's rules read) into a :class:`Grid`."""
    meta = occupancy.read_meta(yaml_path, rotated_ok=True)
    try:
        data = occupancy.read_image(occupancy.image_path(yaml_path, meta["image"]))
        width, height, cells = _cells_of_image(data, meta)
    except OSError as exc:
        raise ConfigError(yaml_path, "image", "cannot read {}: {}".format(shown(meta["image"]), exc.strerror))
    except ValueError as exc:
        raise ConfigError(yaml_path, "image", "{}: {}".format(shown(meta["image"]), exc))
    x, y, yaw = meta["origin"]
    return Grid(width, height, meta["resolution"], x, y, cells, origin_yaw=yaw)


def _cells_of_image(data, meta):
    """(width, height, int8 cells bottom row first); bytes.translate for 8-bit P5, else sim's reader."""
    width, height, maxval, pos = occupancy.pgm_header(data)
    pixels = data[pos + 1:pos + 1 + width * height]
    if data[:2] == b"P5" and maxval == 255 and len(pixels) == width * height:
        table = bytes(v & 0xFF for v in occupancy.cell_table(meta))
        return width, height, flipped_rows(pixels.translate(table), width, height)
    width, height, values = occupancy.parse_pgm(data)
    cells = occupancy.cells_from_pixels(width, height, values, meta)
    return width, height, cells_as_bytes(cells)


def image_size(yaml_path, image):
    """(width, height) from the header of the map's PGM (its first 4 KiB), never its pixels."""
    path = occupancy.image_path(yaml_path, image)
    width, height, _, _ = occupancy.pgm_header(occupancy.read_image(path, head_only=True))
    return width, height

