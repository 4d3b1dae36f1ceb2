"""The map the stack was configured with: listed beside the saved maps, so it can be chosen again.

``--sim`` navigates by default on the simulated world's own map (``sim.map``, else the shipped
demo map), a file outside the maps folder. A mode switch reaches it with map null ("the stack's
own map"); once left for a saved map it could not be chosen again from the page. It is listed in
``GET /maps`` under its file's name (``demo`` for ``config/maps/demo.yaml``) with ``"source":
"configured"``, ``POST /mode`` takes that name for it, and ``GET /mode`` says that name while the
robot navigates on it (``modes/targets.py``: ``Target.configured``). It is not the server's to rename or
delete (its files are the configuration's, not the maps folder's), so both are refused.

On a robot the stack's own map is navigation.launch's ``map`` argument, which the server does not
read: a robot's installed map is ``maps/map.yaml`` in the maps folder (``modes/targets.py``), a
saved map like any other. A saved map of the same name (whatever its case) hides the configured
one: the name means the saved map, and map null still reaches the configured one (``GET /mode``
then says null). Pure: no rospy,
no Flask.
"""

import os
from dataclasses import dataclass
from typing import Optional

from flask_move_server.core.errors import BadMapName

SOURCE = "configured"  # GET /maps "source" of this map; saved maps say "saved"
FALLBACK_NAME = "configured"  # when the file's name cannot name a map


@dataclass(frozen=True)
class ConfiguredMap:
    """The stack's own map: the name a person sees and its YAML."""

    name: str
    path: str

    def answers_to(self, name):
        return isinstance(name, str) and name.casefold() == self.name.casefold()


def of_config(config):
    """The configured map of ``config`` (a ConfiguredMap), or None when the server does not know its file."""
    if not config.sim.enabled or config.stack_kind() not in ("sim", "roslaunch"):
        return None
    path = config.sim.map
    if not path:
        from flask_move_server.sim.demo_map import default_map  # the sim's, only when it runs

        path = default_map()
    return ConfiguredMap(name_of(path), os.path.abspath(path))


def name_of(path):
    """The name a person sees for the map at ``path``: its file's name without ``.yaml``."""
    from flask_move_server.maps.catalogue import check_map_name

    stem = os.path.basename(path)
    stem = stem[:-len(".yaml")] if stem.lower().endswith(".yaml") else stem
    try:
        return check_map_name(stem)
    except BadMapName:
        return FALLBACK_NAME


def unshadowed(configured, saved_names) -> Optional[ConfiguredMap]:
    """``configured`` unless a saved map answers to its name (then that name means the saved map)."""
    if configured is None or any(configured.answers_to(name) for name in saved_names):
        return None
    return configured
