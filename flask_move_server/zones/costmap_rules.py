"""Whether move_base's costmaps, configured as given, read the zones' mask: costmap_2d's rules.

The real costmaps read ``keepout_map`` through a ``costmap_2d::StaticLayer`` (config/costmap_zones.yaml,
loaded over config/global_costmap.yaml and config/local_costmap.yaml in navigation).
:func:`keepout_problems` applies what that layer does (Noetic's
``costmap_2d/plugins/static_layer.cpp``, ``src/costmap_layer.cpp``, ``src/layered_costmap.cpp``) to a
costmap's parameters and says why it would not keep the robot out of the zones, or nothing:

- a StaticLayer in ``plugins`` whose ``map_topic`` (default ``map``) is the mask's topic, ``enabled``;
- ``use_maximum: true``: without it the layer writes every cell of its bounds over what the layers
  before it wrote (``updateWithTrueOverwrite``), so the mask's free cells would erase the map's walls;
- ``first_map_only: false``: with it the layer keeps the first mask and ignores every later one,
  so a zone switched on or off would not reach the costmap until move_base restarts;
- the mask's 100 read as LETHAL (``interpretValue``: not the ``unknown_cost_value``);
- the mask's -1 (no zone: ``zones/mask.py``) read as NO_INFORMATION in a costmap that is not a rolling
  window (``track_unknown_space: true``), which ``updateWithMax`` skips: read as free, it would be
  written over the unknown cells of the map and navfn would plan through space the map never saw;
  and read as FREE in a rolling window (``track_unknown_space: false``), where the layer takes the
  max of its cell and the master's per cell and NO_INFORMATION (255) would win everywhere;
- before the first ``costmap_2d::InflationLayer``: the inflation layer inflates the lethal cells
  the master grid holds when it runs, so a layer after it would keep the robot's centre out of a
  zone and let its body in;
- ``map_topic``, ``unknown_cost_value``, ``lethal_cost_threshold`` and ``track_unknown_space`` set
  on the costmap itself are copied into every StaticLayer over the layer's own
  (costmap_2d_ros.cpp ``copyParentParameters``): a costmap-level ``map_topic`` makes the keepout layer
  read the map.

(Noetic's navigation at 9ad6441: static_layer.cpp 62-124 onInitialize, 150-164 interpretValue,
166-225 incomingMap, 299-344 updateCosts; costmap_layer.cpp 63-106; layered_costmap.cpp 112-155;
inflation_layer.cpp 219-231; costmap_2d_ros.cpp 269-275.)

:func:`move_base_costmaps` merges the YAML files of a navigation config folder as
``launch/include/move_base.launch`` loads them (costmap_common.yaml into both costmaps, then
global_costmap.yaml, local_costmap.yaml, then costmap_zones.yaml in navigation or move_base_mapping.yaml
while mapping), so
the simulated move_base obeys the zones exactly when the real one would. Pure: PyYAML only.
"""

import copy
import os

import yaml

STATIC = "costmap_2d::StaticLayer"
INFLATION = "costmap_2d::InflationLayer"
LETHAL_OBSTACLE, FREE_SPACE, NO_INFORMATION = 254, 0, 255
COSTMAPS = ("global_costmap", "local_costmap")


def move_base_costmaps(folder, mapping=False):
    """``{"global_costmap": params, "local_costmap": params}`` as roslaunch gives them to move_base."""
    common = _read(folder, "costmap_common.yaml")
    tree = {name: copy.deepcopy(common) for name in COSTMAPS}
    files = ["global_costmap.yaml", "local_costmap.yaml", "move_base_mapping.yaml" if mapping else "costmap_zones.yaml"]
    for name in files:
        _merge(tree, {k: v for k, v in _read(folder, name).items() if k in COSTMAPS})
    return tree


PARENT_KEYS = ("map_topic", "unknown_cost_value", "lethal_cost_threshold", "track_unknown_space")


def keepout_layer(costmap, topic):
    """``(index in plugins, params)`` of the StaticLayer reading ``topic``, or None.

    Its params as the layer reads them: the costmap's own values of :data:`PARENT_KEYS` over its own."""
    for index, plugin in enumerate(costmap.get("plugins") or []):
        if isinstance(plugin, dict) and plugin.get("type") == STATIC:
            params = dict(costmap.get(plugin.get("name"), {}) or {})
            params.update({key: costmap[key] for key in PARENT_KEYS if key in costmap})
            if str(params.get("map_topic", "map")).lstrip("/") == topic.lstrip("/"):
                return index, params
    return None


def keepout_problems(costmap, topic):
    """Why ``costmap`` (one costmap's params) would not keep the robot out of the zones on ``topic``; [] if it would."""
    found = keepout_layer(costmap, topic)
    if found is None:
        return ["no costmap_2d::StaticLayer reads {} (map_topic)".format(topic)]
    index, params = found
    problems = []
    if not params.get("enabled", True):
        problems.append("the keepout layer is disabled (enabled: false)")
    if not params.get("use_maximum", False):
        problems.append("use_maximum is false: the mask's free cells would overwrite the map's walls")
    if params.get("first_map_only", False):
        problems.append("first_map_only is true: a zone switched on or off never reaches the costmap")
    if interpret(params, 100) != LETHAL_OBSTACLE:
        problems.append("a zone's cells (100) are not read as lethal (unknown_cost_value 100?)")
    no_zone = interpret(params, -1)
    if costmap.get("rolling_window", False) and no_zone != FREE_SPACE:
        problems.append("the mask's cells outside the zones (-1) are not read as free in this rolling window "
                        "(track_unknown_space must be false): they would make every cell unknown")
    if not costmap.get("rolling_window", False) and no_zone != NO_INFORMATION:
        problems.append("the mask's cells outside the zones (-1) are not read as unknown (track_unknown_space must "
                        "be true): they would make the space the map never saw free")
    inflation = [i for i, p in enumerate(costmap.get("plugins") or []) if isinstance(p, dict)
                 and p.get("type") == INFLATION]
    if inflation and index > inflation[0]:
        problems.append("the keepout layer comes after the inflation layer: the robot's body would enter a zone")
    return problems


def interpret(params, value):
    """StaticLayer::interpretValue: an OccupancyGrid cell value as a cost, by the layer's params."""
    value &= 0xFF
    unknown = int(params.get("unknown_cost_value", -1)) & 0xFF
    lethal = max(min(int(params.get("lethal_cost_threshold", 100)), 100), 0)
    track_unknown = params.get("track_unknown_space", True)
    if value == unknown:
        return NO_INFORMATION if track_unknown else FREE_SPACE
    if value >= lethal:
        return LETHAL_OBSTACLE
    if params.get("trinary_costmap", True):
        return FREE_SPACE
    return int(value / lethal * LETHAL_OBSTACLE)


def obeys_zones(folder, topic, mapping=False):
    """``(True, [])`` when both costmaps of ``folder`` keep out of the zones on ``topic``, else ``(False, why)``."""
    try:
        tree = move_base_costmaps(folder, mapping)
    except (OSError, yaml.YAMLError, AttributeError, TypeError) as exc:
        return False, ["cannot read the costmap configuration: {}".format(exc)]
    why = ["global_costmap: {}".format(p) for p in keepout_problems(tree["global_costmap"], topic)]
    return not why, why


def _read(folder, name):
    with open(os.path.join(folder, name), encoding="utf-8") as f:
        data = yaml.safe_load(f) or {}
    if not isinstance(data, dict):
        raise TypeError("{} does not hold a mapping".format(name))
    return data


def _merge(into, data):
    """rosparam load: mappings merge key by key, anything else (a list, a number) replaces."""
    for key, value in data.items():
        if isinstance(value, dict) and isinstance(into.get(key), dict):
            _merge(into[key], value)
        else:
            into[key] = copy.deepcopy(value)
