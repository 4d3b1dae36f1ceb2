"""Where a mode switch goes (:class:`Target`), and where the server goes at start-up without a choice.

:class:`Targets` turns a request (a mode, a map name, a pose or a waypoint name) into a checked
Target against the maps folder, before anything is stopped, and the remembered choice into the
one to come back to. Pure: no rospy, no Flask.
"""

import logging
import os
from dataclasses import dataclass
from typing import Optional

from flask_move_server.core.errors import BadMapName, BadRequest, MapFileError, UnknownMap, shown
from flask_move_server.core.geometry import Pose2D
from flask_move_server.maps import configured as configured_map
from flask_move_server.maps.catalogue import check_map_name
from flask_move_server.modes import relocalizing

log = logging.getLogger(__name__)

MODES = ("idle", "mapping", "navigation")

OUTSIDE = "the navigation stack is started outside this server (modes.stack: none)"
IDLE = "idle: no navigation stack runs; start mapping with POST /mode {\"mode\": \"mapping\"} (robotctl map start)"


@dataclass(frozen=True)
class Target:
    """Where a switch goes: the mode, its map (name and yaml; None: the stack's own), the pose to set."""

    mode: str
    map: Optional[str] = None
    yaml: Optional[str] = None
    pose: Optional[Pose2D] = None
    note: Optional[str] = None  # the message once running, when the mode has something to say
    configured: Optional[str] = None  # navigation on the stack's own map (map None): its name, as GET /maps lists it

    @property
    def shown_map(self):
        """The map's name as ``GET /mode`` says it: a saved map's, the configured map's, or None."""
        return self.map or self.configured

    def describe(self):
        if self.mode == "navigation":
            return "navigation on the map {!r}".format(self.map) if self.map else "navigation on the stack's own map"
        return self.mode


# The map a robot set up before the server ran its stack navigated on: map_saver's
# maps/map.yaml, navigation.launch's default, as the earlier docs had operators save it.
UPGRADED_MAP = "map"


def default_target(stack_kind, has_upgraded_map=False):
    """Nothing remembered: ``--sim`` navigates on its own map (as it always did); a robot navigates on
    ``maps/map.yaml`` when it has one (a robot upgraded from running navigation.launch itself), else
    waits idle."""
    if stack_kind == "sim":
        return Target("navigation")
    if has_upgraded_map:
        return Target("navigation", map=UPGRADED_MAP)
    return Target("idle", note=IDLE)


def unusable_map_target(name, why):
    """The remembered map cannot be used (``why``: it is gone, its name is bad): idle, saying what to do."""
    return Target("idle", note="idle: the map {!r} used before the restart {}; GET /maps lists the saved maps, "
                               "POST /mode {{\"mode\": \"navigation\", \"map\": NAME}} uses one".format(name, why))


class Targets:
    """Checked targets on the maps folder ``catalogue``, for the server configured by ``config``."""

    def __init__(self, config, catalogue):
        self.config = config
        self.catalogue = catalogue
        self.configured = configured_map.of_config(config)  # the stack's own map, chosen by its name too

    def of(self, mode, map_name=None, pose=None):
        """The Target of a request; BadRequest, BadMapName, UnknownMap, MapFileError (a broken map: nothing
        would come up on it, so nothing is stopped for it) and the pose's errors refuse."""
        if mode not in MODES:
            raise BadRequest("Unknown mode {}: use one of {}.".format(shown(mode), ", ".join(MODES)))
        if mode != "navigation" and (map_name is not None or pose is not None):
            raise BadRequest("Only the navigation mode takes a 'map' and a 'pose'.")
        yaml_path = None
        if self._is_configured(map_name):
            map_name = None  # the stack's own map: map null, as before it had a name
        if map_name is not None:
            map_name = check_map_name(map_name)  # in NFC; BadMapName for a name no map can have
            yaml_path = self.catalogue.yaml_path(map_name)
            if not os.path.isfile(yaml_path):
                raise self._unknown(map_name)
            self._refuse_broken(map_name)
        if isinstance(pose, str):
            pose = relocalizing.waypoint_pose(self.waypoints_path(map_name), pose, map_name)
        own = self._own_name() if mode == "navigation" and map_name is None else None
        return Target(mode, map_name, yaml_path, pose, configured=own)

    def _is_configured(self, name):
        """Does ``name`` mean the stack's own map (no saved map answers to it)?"""
        return self.configured is not None and self.configured.answers_to(name) and self._own_name() is not None

    def _own_name(self):
        """The name the stack's own map is listed under in ``GET /maps``; None when it is not listed."""
        own = configured_map.unshadowed(self.configured, self.catalogue.names()) if self.configured else None
        return own.name if own is not None else None

    def _refuse_broken(self, name):
        problem = self.catalogue.describe(name).problem
        if problem:
            raise MapFileError("The map {!r} cannot be used: {}; fix or replace its files (GET /maps says what "
                               "is wrong with each map).".format(name, problem))

    def _unknown(self, name):
        try:
            self.catalogue.describe(name)
        except UnknownMap as exc:
            return exc
        return UnknownMap("No map named {!r}.".format(name))

    def waypoints_path(self, map_name):
        """The waypoints file that goes with ``map_name`` (None: the single waypoints file)."""
        return self.catalogue.waypoints_path(map_name) if map_name else self.config.waypoints.file

    def remembered(self, remembered, reason):
        """Where to come back to at start-up, from ``state_file.load``'s answer; never raises."""
        if remembered is None:
            if reason:
                log.warning("cannot come back to the mode before the restart: %s; starting the default", reason)
            else:
                log.info("no mode remembered yet: starting the default")
            target = default_target(self.config.stack_kind(), self.catalogue.exists(UPGRADED_MAP))
            return self.of(target.mode, target.map) if target.mode == "navigation" else target
        mode, map_name = remembered
        try:
            return self.of(mode, map_name)
        except (UnknownMap, BadMapName, MapFileError) as exc:
            log.warning("cannot come back to the map %r: %s", map_name, exc)
            why = {UnknownMap: "is gone", BadMapName: "has a bad name"}.get(type(exc), "is broken")
            return unusable_map_target(map_name, why)
