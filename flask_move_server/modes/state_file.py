"""The mode to come back to after a restart: ``{"mode", "map"}`` in a small JSON file.

Written atomically (temporary file, fsync, rename, fsync of the folder: the waypoints
file's plumbing), so a power cut leaves the old or the new choice, never half of one.
Reading never raises: a missing or broken file (any parse failure: bad JSON, 5,000 nested
brackets) means "no choice remembered", and the reason is returned for the log. Pure: no
rospy, no Flask.
"""

import json
import os

from flask_move_server.core.errors import WaypointFileError
from flask_move_server.modes.targets import MODES
from flask_move_server.waypoints import locked_file as waypoints_file


def save(path, mode, map_name):
    """Remember ``mode`` (and ``map_name`` for navigation) in ``path``."""
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    text = json.dumps({"mode": mode, "map": map_name}) + "\n"
    waypoints_file.atomic_write(os.path.abspath(path), text)


def load(path):
    """``((mode, map), None)`` as remembered; ``(None, reason)`` when the file is broken; ``(None, None)`` if none."""
    try:
        text = waypoints_file.read(path)
    except WaypointFileError as exc:
        return None, str(exc)
    if text is None:
        return None, None
    try:
        data = json.loads(text)
    except RecursionError:
        return None, "{} is not valid JSON: nested too deeply".format(path)
    except ValueError as exc:
        return None, "{} is not valid JSON: {}".format(path, exc)
    if not isinstance(data, dict) or data.get("mode") not in MODES:
        return None, "{} does not name a mode ({})".format(path, ", ".join(MODES))
    map_name = data.get("map")
    if map_name is not None and (data["mode"] != "navigation" or not isinstance(map_name, str)):
        return None, "{}: only navigation takes a map, given as text".format(path)
    return (data["mode"], map_name), None
