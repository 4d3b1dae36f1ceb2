"""Where the recorder's waypoints go: the running server's API, or the YAML file.

Both savers offer the same small interface (``all``, ``put``, ``delete``,
``rename``) so the session does not care which one it has. The server is the
one writer when it answers; otherwise the file is written through the same
:class:`~flask_move_server.waypoints.store.WaypointStore` the server uses (fcntl lock
+ atomic save), so neither loses the other's edits.
"""

from flask_move_server.core.errors import ClientError, WaypointFileError
from flask_move_server.robotctl.api import ExitStatus, RobotClient, waypoint_path
from flask_move_server.waypoints import make_waypoint
from flask_move_server.waypoints.store import WaypointStore


class FileSaver:
    """Waypoints saved straight to the YAML file (lock + atomic save)."""

    def __init__(self, path):
        self.store = WaypointStore(path)
        self.where = "the file {}".format(self.store.path)
        if self.store.problem:  # refused before the first click, not at every save
            raise WaypointFileError("{}; fix it before recording".format(self.store.problem))

    def all(self):
        return self.store.all()

    def put(self, waypoint):
        return self.store.put(waypoint)

    def delete(self, name):
        self.store.delete(name)

    def rename(self, old, new):
        self.store.rename(old, new)

    def close(self):
        """Nothing to release: the lock is held only while saving."""


class ServerSaver:
    """Waypoints saved through the running server's API (the server writes the file)."""

    def __init__(self, client):
        self.client = client
        self.where = "the server at {}".format(client.url)

    def all(self):
        return [make_waypoint(w["name"], w["x"], w["y"], w["yaw"]) for w in self.client.get("/waypoints")["waypoints"]]

    def put(self, waypoint):
        body = {"x": waypoint.x, "y": waypoint.y, "yaw": waypoint.yaw}
        return bool(self.client.put(waypoint_path(waypoint.name), body).get("created"))

    def delete(self, name):
        self.client.delete(waypoint_path(name))

    def rename(self, old, new):
        """One ``PATCH``: the server renames in one save (never both names, or neither, on disk)."""
        if old != new:
            self.client.request("PATCH", waypoint_path(old), {"name": new})

    def close(self):
        self.client.close()


def choose_saver(waypoints_file, server_url=None, token=None, say=print):
    """The server's API when ``server_url`` answers, else the file; says which."""
    if server_url:
        client = RobotClient(server_url, token, timeout=3.0)
        try:
            client.get("/waypoints")
        except ClientError as exc:
            client.close()
            if exc.exit_status != ExitStatus.UNREACHABLE:
                raise
            say("The server at {} does not answer; saving to {} directly.".format(server_url, waypoints_file))
        else:
            return ServerSaver(client)
    return FileSaver(waypoints_file)
