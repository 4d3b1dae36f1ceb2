"""What the map routes call: the map in use and its image, the maps folder, saving, per-map waypoints.

:class:`MapService` joins the parts the web layer must not know: the live map
(a :class:`~flask_move_server.ros.map_source.MapSource`, or anything with
``held_version()``, ``current()``, ``latest(timeout)``, ``context``), the
maps folder (:class:`~flask_move_server.maps.catalogue.MapCatalogue`), the
mode manager (``status()``, ``active_map``, ``switch(mode, map_name)``; None
when nothing manages the stack) and the waypoint store.

Per-map waypoints: the store follows the mode's map. On every ``mode`` event
it serves ``NAME.waypoints.yaml`` of the saved map named there; while mapping,
the map being made's own marks (``maps/marks.py``: emptied when mapping starts,
given to the map when it is saved); else the single ``waypoints.file`` (idle,
navigation on the stack's own map, named there by its listed name or null). Every change of the served set publishes a
``waypoints`` event ``{"map", "version"}``. Only when the server cannot tell
mapping from navigation (``modes.stack: none``) does the first map saved into an
empty folder adopt a copy of the single file's waypoints (the single file is
never moved or emptied).

The stack's own map (``maps/configured.py``) is listed with the saved ones under
its file's name; it can be described, drawn and chosen, not renamed nor deleted.
Pure: no rospy, no Flask.
"""

import logging
import os
import threading
import uuid

from flask_move_server.core.errors import (
    MapConfigured,
    MapExists,
    MapFileError,
    ModesOff,
    MoveServerError,
    NoMap,
    WrongMode,
)
from flask_move_server.maps import configured as configured_map
from flask_move_server.maps import render
from flask_move_server.maps.catalogue import check_map_name
from flask_move_server.maps.file_cache import FileVersionCache
from flask_move_server.maps.map_info import describe_file, file_version
from flask_move_server.maps.marks import FILE_NAME as MARKS_FILE
from flask_move_server.maps.marks import MappingMarks
from flask_move_server.waypoints import locked_file as waypoints_file

log = logging.getLogger(__name__)


class MapService:
    """The live map, the saved maps, and which waypoints file is served."""

    def __init__(self, catalogue, store, source=None, modes=None, events=None, margin=1.0, save_timeout=10.0,
                 configured=None, marks=None):
        """``configured``: the stack's own map (a ConfiguredMap, or None); ``marks``: the MappingMarks
        (default: ``mapping.waypoints.yaml`` beside the waypoints file)."""
        self.catalogue = catalogue
        self.store = store
        self.source = source
        self.modes = modes
        self.events = events
        self.margin = margin
        self.save_timeout = save_timeout
        self.single_file = store.path
        self.configured = configured
        self._own_facts = FileVersionCache()  # the configured map's facts, read once per version of its files
        self.marks = marks or MappingMarks(os.path.join(os.path.dirname(store.path), MARKS_FILE), store.lock_timeout)
        self.waypoints_map = None  # the map whose waypoints the store serves (None: the single file)
        self._following = None  # the mode whose waypoints the store serves
        self._run = uuid.uuid4().hex[:8]  # in the live ETag: versions restart at 1 with the process
        self._live = render.ImageCache(size=2)
        self._saved = render.ImageCache(size=8)
        self._save_lock = threading.Lock()
        store.when_changed(self._waypoints_changed)
        if source is not None:
            source.mode_of = self._managed_mode
        if events is not None:
            events.listen("mode", self._on_mode)
            events.publish("waypoints", {"map": None, "version": store.version})  # for streams opened from now
        if modes is not None:
            self.use_modes(modes)

    # the mode's map and its waypoints ------------------------------------------------------

    def use_modes(self, modes):
        """Take ``modes`` as the mode manager (also after construction) and serve its map's waypoints."""
        self.modes = modes
        self.follow(modes.status())

    @property
    def active_map(self):
        """The saved map in use now (None: no named map, or no mode manager)."""
        return self.modes.active_map if self.modes is not None else None

    def mode(self):
        """``{"mode", "map"}`` now: the mode manager's, else the last ``mode`` event's."""
        managed = self._managed_mode()
        if managed is not None:
            return managed
        if self.source is not None:
            return self.source.context
        return {"mode": None, "map": None}

    def _managed_mode(self):
        if self.modes is None:
            return None
        status = self.modes.status()
        return {"mode": status.get("mode"), "map": status.get("map")}

    def _on_mode(self, status):
        self.follow(status)

    def follow(self, status):
        """Serve the waypoints of the mode ``status`` names: its map's, the marks while mapping, or the single file."""
        mode, name = status.get("mode"), status.get("map")
        if name and not self._is_own(name):
            path = self.catalogue.waypoints_path(name)
        elif mode == "mapping" and self._switches_modes():
            if self._following != "mapping":
                self._start_marks()
            path = self.marks.path
        else:
            path = self.single_file
        renamed = name != self.waypoints_map and os.path.abspath(path) == self.store.path
        self._following, self.waypoints_map = mode, name
        self.store.use_file(path)
        if renamed:  # the same file under another name (the configured map's, or null): said all the same
            self._waypoints_changed(self.store.version)

    def _start_marks(self):
        try:
            self.marks.start_afresh()
        except (OSError, MoveServerError) as exc:  # never fail a mode switch: the log says why
            log.error("cannot empty %s for the new map's places: %s", self.marks.path, exc)

    def _waypoints_changed(self, version):
        if self.events is not None:
            self.events.publish("waypoints", {"map": self.waypoints_map, "version": version})

    # the live map --------------------------------------------------------------------------

    def live_etag(self):
        """The ETag of ``/map/image`` now, without rendering; NoMap when no map is published."""
        return "{}-{}".format(self._run, self._source().held_version())

    def live_image(self):
        """``(etag, MapImage)`` of the map in use (rendered once per version); NoMap when none."""
        version = self._source().held_version()
        image = self._live.get(version)
        if image is None:
            version, grid = self._source().current()
            image = self._live.image(version, lambda: render.render(grid, self.margin, version=str(version)))
        return "{}-{}".format(self._run, version), image

    def live_metadata(self):
        """``GET /map``: the crop ``/map/image`` serves (pixel → metres), its version, the mode and map."""
        _, image = self.live_image()
        meta = image.metadata()
        meta["version"] = int(image.version)
        meta.update(self.mode())
        return meta

    def _source(self):
        if self.source is None:
            raise NoMap("This server does not follow a map topic, so it has no map in use.")
        return self.source

    # the maps folder -----------------------------------------------------------------------

    def list(self):
        """``GET /maps``: the stack's own map first (when listed), then the saved maps by name."""
        saved = self.catalogue.list()
        own = self._own_map([info.name for info in saved])
        infos = ([self._own_info(own)] if own else []) + saved
        return {"maps": [info.as_dict() for info in infos], "active": self._active_name(own)}

    def describe(self, name):
        own = self._own_map()
        if own is not None and own.answers_to(name):
            return dict(self._own_info(own).as_dict(), active=self._active_name(own) == own.name)
        return dict(self.catalogue.describe(name).as_dict(), active=name == self.active_map)

    def _own_map(self, saved_names=None):
        """The configured map, unless there is none or a saved map has its name."""
        if self.configured is None:
            return None
        return configured_map.unshadowed(self.configured, self.catalogue.names() if saved_names is None
                                         else saved_names)

    def _is_own(self, name):
        """Does ``name`` (a mode's map) mean the configured map? Its places are the single waypoints file's."""
        own = self._own_map()
        return own is not None and own.answers_to(name)

    def _own_info(self, own):
        try:
            return describe_file(own.name, own.path, self.single_file, configured_map.SOURCE, self._own_facts)
        except OSError as exc:
            raise MapFileError("The configured map {} cannot be read: {}.".format(own.path, exc.strerror)) from exc

    def _active_name(self, own):
        """The name of the map in use: a saved map's, the configured map's (its name in /mode), or None."""
        if self.active_map is not None or own is None or not self._switches_modes():
            return self.active_map
        status = self.modes.status()
        return own.name if status.get("mode") == "navigation" and status.get("map") in (None, own.name) else None

    def saved_image(self, name):
        """``(etag, MapImage)`` of a saved map (rendered once per file version)."""
        version, load = self._image_source(name)
        return version, self._saved.image(version, lambda: render.render(load(), self.margin, version=version))

    def saved_etag(self, name):
        return self._image_source(name)[0]

    def _image_source(self, name):
        """``(version, load)`` of a listed map's image: a saved map's, or the configured map's."""
        own = self._own_map()
        if own is None or not own.answers_to(name):
            return self.catalogue.version(name), lambda: self.catalogue.load(name)
        from flask_move_server.maps import mapfile  # the configured map is read as map_server would

        return file_version(own.name, own.path, mapfile.named_image(own.path) or own.path), \
            lambda: self._load_own(own, mapfile)

    def _load_own(self, own, mapfile):
        try:
            return mapfile.load(own.path)
        except (OSError, MoveServerError) as exc:
            raise MapFileError("The configured map {} cannot be read: {}".format(own.path, exc)) from exc

    def delete(self, name):
        self._refuse_configured(name, "deleted")
        self.catalogue.delete(name, active=self.active_map)

    def rename(self, old, new):
        self._refuse_configured(old, "renamed")
        self._refuse_configured_name(new)
        return self.describe(self.catalogue.rename(old, new, active=self.active_map).name)

    def _refuse_configured(self, name, done):
        own = self._own_map()
        if own is not None and own.answers_to(name):
            raise MapConfigured("The map {!r} is the one the robot's stack was configured with ({}): it is not in "
                                "the maps folder, so it cannot be {} here.".format(own.name, own.path, done))

    def _refuse_configured_name(self, name):
        """A saved map may not take the configured map's name: it would hide that map from the list."""
        own = self._own_map()
        if own is not None and own.answers_to(name):
            raise MapExists("{!r} is the name of the robot's own map (the one its navigation was set up with); "
                            "pick another name.".format(own.name))

    # saving --------------------------------------------------------------------------------

    def save(self, name, overwrite=False, then=None, here=None):
        """Save the latest map as ``name`` (mapping mode only); with ``then``, switch to it.

        ``here``: the robot's pose in the map being saved (None: unknown). Switching straight to
        the map keeps it there: the saved map has the mapping's frame, so that pose is right, and
        the map's dock (a guess of where the robot stands) would be wrong.

        Checked before waiting for a map: the name, the mode, an existing name. The map
        files are written atomically; when adopting the waypoints fails, a map new under
        this name is deleted again, so nothing is left half-saved.
        """
        name = check_map_name(name)
        self._require_mapping()
        if then and not self._switches_modes():
            raise ModesOff("This server does not start the navigation stack (modes.stack: none), so it cannot "
                           "\"then\" switch to the map; save it without \"then\" and start navigation on it "
                           "with your own launch file.")
        self.check_new_name(name, overwrite)
        _, grid = self.source.latest(self.save_timeout)
        with self._save_lock:
            first = not self.catalogue.names()
            existed = self.catalogue.exists(name)
            self.catalogue.save(name, grid, overwrite=overwrite)
            adopted = False
            if self.store.path == self.marks.path:
                self._give_marks(name, existed)
            elif first:
                adopted = self._adopt_waypoints(name, existed)
        result = {"status": "ok", "map": self.describe(name), "adopted_waypoints": adopted}
        if then:
            result.update(self._switch_to(name, here))
        return result

    def check_new_name(self, name, overwrite=False):
        """The checked ``name`` a map may be saved as now: BadMapName, MapConfigured, MapExists (unless
        ``overwrite``) say why not. Also asked before an exploration starts, so a taken name is refused
        before the robot moves rather than after it mapped the flat."""
        name = check_map_name(name)
        self.catalogue.refuse_case_twin(name)
        self._refuse_configured_name(name)
        if not overwrite and self.catalogue.exists(name):
            raise MapExists("A map named {!r} is already saved; send \"overwrite\": true to replace it, "
                            "or pick another name.".format(name))
        return name

    def _switches_modes(self):
        return self.modes is not None and self.modes.runs_stack

    def _require_mapping(self):
        if self.source is None:
            raise WrongMode("This server follows no map topic, so there is no map being made to save.")
        if not self._switches_modes():
            return  # the stack is run elsewhere (modes.stack: none): whatever publishes the map is saved
        mode = self.modes.status().get("mode")
        if mode != "mapping":
            raise WrongMode("Saving a map needs mapping mode, and the robot is in {} mode: start mapping first "
                            "(POST /mode {{\"mode\": \"mapping\"}}, robotctl map start).".format(mode))

    def _give_marks(self, name, existed):
        """The places marked while mapping become the saved map's (an overwritten map's old ones go to .bak)."""
        try:
            self.marks.give_to(self.catalogue.waypoints_path(name))
        except (OSError, MoveServerError) as exc:
            if not existed:
                self.catalogue.delete(name)
            raise MapFileError("Could not write the places marked while mapping to the map {!r} ({}); {}".format(
                name, getattr(exc, "strerror", None) or exc,
                "the map was saved, its old places kept." if existed else "the map was not saved.")) from exc

    def _adopt_waypoints(self, name, existed):
        """The first map: a copy of the single file's waypoints, unless the map has its own; True if copied."""
        target = self.catalogue.waypoints_path(name)
        try:
            text = waypoints_file.read(self.single_file)
            if text is None or os.path.exists(target):
                return False
            waypoints_file.atomic_write(target, text)
            return True
        except (OSError, MoveServerError) as exc:
            if not existed:
                self.catalogue.delete(name)
            raise MapFileError("Could not copy the waypoints of {} to the new map {!r} ({}); the map was not "
                               "saved.".format(self.single_file, name, getattr(exc, "strerror", None) or exc)) from exc

    def _switch_to(self, name, here=None):
        """``"then": "navigation"``: switch to the saved map; the save stands even if the switch is refused."""
        try:
            return {"mode": self.modes.switch("navigation", name, pose=here)}
        except MoveServerError as exc:
            return {"mode_error": {"error": exc.code, "message": str(exc)}}
