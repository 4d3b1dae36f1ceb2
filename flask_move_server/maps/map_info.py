"""What a map's files say: its line in the maps list (:class:`MapInfo`) and the facts under it.

A map YAML in the folder is read by map_server's rules (``sim/occupancy``; a link must resolve
into the folder), its image's size from the image's header (``maps/mapfile``), its waypoints
counted from ``NAME.waypoints.yaml``; a broken map is listed with the ``problem`` saying what is
wrong. :func:`file_version` is the files' version for an ETag. The catalogue
(``maps/catalogue.py``) keeps the folder: names, listing, saving, renaming, deleting, leftovers.
Pure: no rospy, no Flask.
"""

import datetime
import os
from dataclasses import dataclass

from flask_move_server.config import guarded_yaml
from flask_move_server.core.errors import ConfigError, shown
from flask_move_server.maps import mapfile
from flask_move_server.sim import occupancy
from flask_move_server.waypoints import locked_file as waypoints_file
from flask_move_server.waypoints.yaml_format import entries_of


@dataclass(frozen=True)
class MapInfo:
    """What the maps list says of one map; ``problem`` names what is wrong with a broken one."""

    name: str
    width: object
    height: object
    resolution: object
    origin: object
    modified: str
    waypoints: int
    problem: object = None
    source: str = "saved"  # "configured": the stack's own map (maps/configured.py)

    def as_dict(self):
        data = {"name": self.name, "width": self.width, "height": self.height, "resolution": self.resolution,
                "origin": self.origin, "modified": self.modified, "waypoints": self.waypoints,
                "source": self.source}
        if self.problem:
            data["problem"] = self.problem
        return data

MAP_SAVER_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh")

def map_meta(yaml_path):
    """map_server's checked keys of a map YAML in the folder; a symlink must resolve into the folder."""
    if not occupancy.inside(os.path.dirname(yaml_path), yaml_path):
        raise ConfigError(yaml_path, None, "a symbolic link to a file outside the maps folder; copy the map "
                                           "into the folder instead")
    return occupancy.read_meta(yaml_path, rotated_ok=True)

def raw_meta(yaml_path):
    """The YAML's mapping as written (extra keys kept), checked by map_server's rules first."""
    map_meta(yaml_path)
    try:
        return guarded_yaml.read(yaml_path, occupancy.MAX_YAML_BYTES)
    except guarded_yaml.Unreadable as exc:  # changed since it was checked
        raise ConfigError(yaml_path, None, str(exc)) from None

def file_version(name, *paths):
    """A version of a map's files for an ETag: each one's change time and size ("none" when missing)."""
    parts = [name]
    for path in paths:
        try:
            info = os.stat(path)
            parts.append("{:x}-{:x}".format(info.st_mtime_ns, info.st_size))
        except FileNotFoundError:
            parts.append("none")
    return "-".join(parts)

def describe_file(name, yaml_path, waypoints_path, source, cache):
    """The :class:`MapInfo` of a map outside the folder (the configured one); OSError if it is gone.

    ``cache``: a FileVersionCache, so its YAML and image header are read once per version.
    """
    modified = iso_time(os.stat(yaml_path).st_mtime)
    facts, _ = cache.get(yaml_path, lambda: facts_of(yaml_path))
    count, _ = cache.get(waypoints_path, lambda: (count_entries(waypoints_path), ()))
    return MapInfo(name, facts["width"], facts["height"], facts["resolution"], facts["origin"], modified, count,
                   problem=facts["problem"], source=source)

def facts_of(yaml_path):
    """``({width, height, resolution, origin, problem}, [the image's path])`` of a map's YAML."""
    facts = dict.fromkeys(("width", "height", "resolution", "origin", "problem"))
    try:
        meta = map_meta(yaml_path)
    except ConfigError as exc:
        return dict(facts, problem=str(exc)), ()
    try:
        image = occupancy.image_path(yaml_path, meta["image"])
        facts["width"], facts["height"] = mapfile.image_size(yaml_path, meta["image"])
    except (OSError, ValueError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else exc
        problem = "{}: image: {}: {}".format(yaml_path, shown(meta["image"]), reason)
        return dict(facts, problem=problem), ()
    facts.update(resolution=meta["resolution"], origin=list(meta["origin"]))
    return facts, (image,)

def count_entries(waypoints_path):
    try:
        return len(entries_of(waypoints_file.read(waypoints_path) or "", source="waypoints") or {})
    except (OSError, ValueError):
        return 0

def iso_time(timestamp):
    return datetime.datetime.fromtimestamp(timestamp, datetime.timezone.utc).isoformat(timespec="seconds")
