"""The maps folder: every saved map, its facts, and renaming or deleting one with its waypoints.

A map is ``NAME.yaml`` + its image (``NAME.pgm`` as map_saver writes it, so maps
made elsewhere can be dropped in) and, beside them, its waypoints
``NAME.waypoints.yaml`` in the waypoints file format (kept by
:class:`~flask_move_server.waypoints.store.WaypointStore`). A map exists when its
YAML does: :func:`mapfile.save` renames the YAML into place last.

Names follow the waypoint naming rule (:mod:`flask_move_server.core.names`: letters of any
language, in NFC), and since a name becomes a file name, also never start with '.'
(hidden files, the temporaries of a save), nor end in '.waypoints' (it would be another
map's waypoints file), nor take more than :data:`MAX_NAME_BYTES` bytes of UTF-8 (a file
name holds 255, and the temporaries add their suffixes). Two maps' names never differ only
in case or normalisation: a folder on FAT, exFAT or macOS would hold them as one file. Leftovers of a killed
save (``.~NAME.*.part``) are never listed; :meth:`MapCatalogue.remove_leftovers`
deletes them. Mutations take one lock, so two requests cannot interleave a
rename and a save. Pure: no rospy, no Flask.
"""

import logging
import os
import threading

from flask_move_server.core import names as naming
from flask_move_server.core.errors import (
    BadMapName,
    ConfigError,
    MapExists,
    MapFileError,
    MapInUse,
    UnknownMap,
    shown,
)
from flask_move_server.maps import mapfile
from flask_move_server.maps.file_cache import FileVersionCache
from flask_move_server.maps.map_info import (
    MAP_SAVER_KEYS,
    MapInfo,
    count_entries,
    facts_of,
    file_version,
    iso_time,
    map_meta,
    raw_meta,
)
from flask_move_server.waypoints import NAME_RULE, suggest
from flask_move_server.waypoints import locked_file as waypoints_file

log = logging.getLogger(__name__)
WAYPOINTS_SUFFIX = ".waypoints.yaml"
MAX_NAME_BYTES = 200  # the longest derived file name, ".NAME.waypoints.yaml.bak.XXXXXXXX.tmp", adds 33
MAP_NAME_RULE = NAME_RULE + ", not starting with '.' and not ending in '.waypoints'"


def check_map_name(name):
    """``name`` in NFC if it can name a map (and its files), else BadMapName quoting an excerpt of it."""
    name = naming.checked(name, "map name", BadMapName)
    if name.startswith(".") or naming.same_name_key(name).endswith(".waypoints"):
        raise BadMapName("Invalid map name {}: use {}.".format(shown(name), MAP_NAME_RULE))
    if len(name.encode("utf-8")) > MAX_NAME_BYTES:
        raise BadMapName("The map name {} is too long for a file name: {} bytes in UTF-8, at most {} (letters "
                         "of some scripts take 4 bytes each); use a shorter name.".format(
                             shown(name), len(name.encode("utf-8")), MAX_NAME_BYTES))
    return name


class MapCatalogue:
    """The maps of one folder: list, describe, save, load, rename, delete."""

    def __init__(self, folder):
        self.folder = os.path.abspath(folder)
        self._lock = threading.Lock()
        self._facts = FileVersionCache()  # each map's YAML and image header, read once per version
        self._counts = FileVersionCache()  # each map's number of waypoints

    # paths ----------------------------------------------------------------

    def yaml_path(self, name):
        """The YAML of map ``name`` (validated; it may not exist)."""
        return os.path.join(self.folder, check_map_name(name) + ".yaml")

    def waypoints_path(self, name):
        """The waypoints file of map ``name``, for a WaypointStore (it may not exist yet)."""
        return os.path.join(self.folder, check_map_name(name) + WAYPOINTS_SUFFIX)

    def exists(self, name):
        return os.path.isfile(self.yaml_path(name))

    # reading --------------------------------------------------------------

    def names(self):
        """The saved maps' names, sorted; files that cannot be a map name (or not in NFC) are skipped."""
        try:
            files = os.listdir(self.folder)
        except FileNotFoundError:
            return []
        except OSError as exc:
            raise MapFileError("Cannot list the maps folder {}: {}.".format(self.folder, exc.strerror)) from exc
        names = []
        for file in files:
            if file.endswith(".yaml") and not file.endswith(WAYPOINTS_SUFFIX):
                stem = file[:-len(".yaml")]
                try:
                    if check_map_name(stem) == stem:
                        names.append(stem)
                except BadMapName:
                    continue
        return sorted(names)

    def list(self):
        """A :class:`MapInfo` per saved map, sorted by name (a map deleted meanwhile is left out)."""
        infos, names = [], self.names()
        self._facts.keep_only(self.yaml_path(name) for name in names)
        self._counts.keep_only(self.waypoints_path(name) for name in names)
        for name in names:
            try:
                infos.append(self.describe(name))
            except UnknownMap:
                continue
        return infos

    def describe(self, name):
        """The :class:`MapInfo` of one map; UnknownMap (with close names) when it is not saved.

        The YAML and the image's header are read once per version of the files; a broken
        map is logged once per version too, and listed with its ``problem``.
        """
        name = check_map_name(name)
        path = self._existing(name)
        try:
            modified = iso_time(os.stat(path).st_mtime)
        except FileNotFoundError:
            raise self._unknown(name) from None
        facts, new = self._facts.get(path, lambda: facts_of(path))
        if new and facts["problem"]:
            log.warning("the map %r is broken: %s", name, facts["problem"])
        return MapInfo(name, facts["width"], facts["height"], facts["resolution"], facts["origin"], modified,
                       self._count_waypoints(name), problem=facts["problem"])

    def version(self, name):
        """A version of the stored map for an ETag: its YAML's and PGM's change times and sizes."""
        name = check_map_name(name)
        return file_version(name, self._existing(name), os.path.join(self.folder, name + ".pgm"))

    def load(self, name):
        """The map's :class:`~flask_move_server.maps.mapfile.Grid`; MapFileError if its files are broken."""
        name = check_map_name(name)
        path = self._existing(name)
        try:
            map_meta(path)
            return mapfile.load(path)
        except ConfigError as exc:
            raise MapFileError("The map {!r} cannot be read: {}".format(name, exc)) from exc

    def _count_waypoints(self, name):
        return self._counts.get(self.waypoints_path(name), lambda: (count_entries(self.waypoints_path(name)), ()))[0]

    def _existing(self, name):
        path = self.yaml_path(name)
        if not os.path.isfile(path):
            raise self._unknown(name)
        return path

    def _unknown(self, name):
        close = suggest(name, self.names())
        hint = " Did you mean: {}?".format(", ".join(repr(s) for s in close)) if close else \
            " GET /maps lists the saved maps."
        return UnknownMap("No map named {!r}.{}".format(name, hint))

    # changing -------------------------------------------------------------

    def save(self, name, grid, overwrite=False):
        """Save ``grid`` as map ``name`` (atomically; MapExists unless ``overwrite``); its MapInfo."""
        name = check_map_name(name)
        with self._lock:
            self.refuse_case_twin(name)
            self._make_folder()
            mapfile.save(self.folder, name, grid, overwrite=overwrite)
        return self.describe(name)

    def refuse_case_twin(self, name):
        """MapExists naming the saved map whose name differs from ``name`` only in case (or normalisation).

        FAT, exFAT (a USB stick) and macOS fold case: ``Base.yaml`` would be ``base.yaml``
        there (and macOS ``Küche`` composed or not), so map names are unique whatever their case.
        """
        name, key = check_map_name(name), naming.same_name_key(name)
        for saved in self.names():
            if saved != name and naming.same_name_key(saved) == key:
                raise MapExists("A map named {!r} is saved, and map names must differ in more than case (a "
                                "FAT, exFAT or macOS folder cannot hold both); pick another name (to change only "
                                "the case of a map's name, rename it to another name first).".format(saved))

    def rename(self, old, new, active=None):
        """Rename map ``old`` to ``new`` with its image and waypoints; never the ``active`` map.

        Renaming a map to its own name changes nothing (its MapInfo); to a name that differs from
        a saved one (itself included) only in case, MapExists.
        """
        old, new = check_map_name(old), check_map_name(new)
        with self._lock:
            old_yaml = self._existing(old)
            if new == old:
                return self.describe(old)  # nothing to do, even for the map in use
            self._refuse_active(old, active, "renamed")
            self.refuse_case_twin(new)
            if self.exists(new):
                raise MapExists("A map named {!r} already exists; delete it first or pick another name.".format(new))
            try:
                self._move(old, new, old_yaml)
            except ConfigError as exc:
                raise MapFileError("The map {!r} cannot be renamed: {}".format(old, exc)) from exc
            except OSError as exc:
                raise MapFileError("Could not rename the map {!r} to {!r}: {}.".format(
                    old, new, exc.strerror or exc)) from exc
        return self.describe(new)

    def _move(self, old, new, old_yaml):
        """Link every file under the new name, put the new YAML in place, then drop the old names.

        Killed half-way, the folder holds the map twice (or once), never zero times.
        """
        meta = raw_meta(old_yaml)
        image = meta["image"]
        # its own image: NAME.pgm, or the temporary an interrupted save left the YAML naming
        own_image = image == old + ".pgm" or mapfile.is_part(image, old)
        links = [(self.waypoints_path(old) + ext, self.waypoints_path(new) + ext) for ext in ("", ".bak")]
        if own_image:
            links.append((os.path.join(self.folder, image), os.path.join(self.folder, new + ".pgm")))
            meta["image"] = new + ".pgm"
        for source, target in links:
            if os.path.exists(source):
                _replace_link(source, target)
        extra = {k: v for k, v in meta.items() if k not in MAP_SAVER_KEYS}
        text = mapfile.yaml_text(meta["image"], float(meta["resolution"]), meta["origin"], extra)
        part = mapfile.write_part(self.folder, new, ".yaml", text.encode())
        os.rename(part, self.yaml_path(new))
        stale = [os.path.join(self.folder, old + ".pgm")] if own_image else []  # no YAML names it now
        for path in [old_yaml] + [source for source, _ in links] + stale + self._waypoints_leftovers(old):
            _remove_if_there(path)
        waypoints_file.fsync_dir(self.folder)

    def delete(self, name, active=None):
        """Delete map ``name`` (YAML first, so it is gone at once), ``NAME.pgm`` and its waypoints; not the active one.

        A broken map can be deleted too; an image the YAML names under another name is left alone
        (but for the temporary name an interrupted save left it naming).
        """
        name = check_map_name(name)
        with self._lock:
            path = self._existing(name)
            self._refuse_active(name, active, "deleted")
            waypoints = self.waypoints_path(name)
            image = mapfile.named_image(path)
            parts = [image] if image and mapfile.is_part(image, name) else []
            try:
                os.unlink(path)
                for other in [os.path.join(self.folder, name + ".pgm"), waypoints, waypoints + ".bak"] + \
                        parts + self._waypoints_leftovers(name):
                    _remove_if_there(other)
            except OSError as exc:
                raise MapFileError("Could not delete the map {!r}: {}.".format(name, exc.strerror)) from exc

    def _waypoints_leftovers(self, name):
        """The waypoints file's lock and a killed save's temporaries: dropped, never moved."""
        path = self.waypoints_path(name)
        return [path + ".lock"] + waypoints_file.leftovers(path)

    def _refuse_active(self, name, active, done):
        if active is not None and name == active:
            raise MapInUse("The map {!r} is in use; switch to another map (or idle) before it can be {}.".format(
                name, done))

    def _make_folder(self):
        try:
            os.makedirs(self.folder, exist_ok=True)
        except OSError as exc:
            raise MapFileError("Cannot create the maps folder {}: {}.".format(self.folder, exc.strerror)) from exc

    # leftovers ------------------------------------------------------------

    def leftovers(self):
        """Temporary files a killed save or rename left in the folder, but for one a map's YAML names.

        A save killed after the YAML was replaced may leave it naming the new image under its
        temporary name: that image is the map now, and is kept (the next save of the map tidies it).
        """
        try:
            files = os.listdir(self.folder)
        except OSError:
            return []
        named = {os.path.realpath(p) for p in map(mapfile.named_image, self._yaml_paths()) if p}
        parts = (os.path.join(self.folder, f) for f in files if mapfile.is_part(f))
        return sorted(p for p in parts if os.path.realpath(p) not in named)

    def _yaml_paths(self):
        return [os.path.join(self.folder, name + ".yaml") for name in self.names()]

    def remove_leftovers(self):
        """Delete the leftovers (call when no save runs, e.g. at start-up); the paths removed."""
        with self._lock:
            removed = self.leftovers()
            for path in removed:
                _remove_if_there(path)
        return removed


def _replace_link(source, target):
    _remove_if_there(target)
    os.link(source, target)


def _remove_if_there(path):
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


