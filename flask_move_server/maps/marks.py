"""The places marked while mapping: the map being made's own waypoints, until it is saved.

While mapping, ``/waypoints`` serves ``mapping.waypoints.yaml`` in the state folder (beside
``mode.json``), a waypoints file like any other (locked, written atomically, ``.bak``), so the
marks are in the new map's frame and never in another map's file. Each mapping starts it afresh:
a new SLAM map has a new frame (also after a restart of the server, which starts mapping anew),
so older marks would point at the wrong spots. Saving the map writes them as the saved map's
waypoints (``NAME.waypoints.yaml``); leaving mapping without saving leaves them to be emptied by
the next mapping. Pure: no rospy, no Flask.
"""

import os

from flask_move_server.waypoints import locked_file as waypoints_file
from flask_move_server.waypoints.yaml_format import entries_of

FILE_NAME = "mapping.waypoints.yaml"
NONE_YET = "waypoints: {}\n"


class MappingMarks:
    """The waypoints file of the map being made."""

    def __init__(self, path, lock_timeout=3.0):
        self.path = os.path.abspath(path)
        self.lock_timeout = lock_timeout

    def start_afresh(self):
        """Empty the marks (a new map is being made), its ``.bak`` too: they belong to an older map."""
        os.makedirs(os.path.dirname(self.path), exist_ok=True)
        with waypoints_file.file_lock(self.path + ".lock", self.lock_timeout):
            waypoints_file.atomic_write(self.path, NONE_YET)
            _remove_if_there(self.path + ".bak")

    def give_to(self, target):
        """Write the marks as the waypoints file ``target`` (a map's), its old text kept in ``.bak``.

        Nothing is written for a new map when nothing was marked. Raises OSError, WaypointFileError.
        """
        with waypoints_file.file_lock(self.path + ".lock", self.lock_timeout):
            text = waypoints_file.read(self.path) or NONE_YET
            old = waypoints_file.read(target)
            if old is None and not entries_of(text, source=self.path):
                return 0
            waypoints_file.atomic_write(target, text, backup_text=old)
            return len(entries_of(text, source=self.path) or {})


def _remove_if_there(path):
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass
