"""Stand-ins for the map routes' web tests: a mode manager and a live map, each recording its calls.

The map routes know a MapService, which knows a mode manager (``status()``, ``active_map``,
``switch``) and a map source (``held_version()``, ``current()``, ``latest(timeout)``, ``context``).
These answer as those would, in memory, so the routes' checks and shapes test in milliseconds;
the real MapSource on a real ROS topic is tests/test_map_source.py's.
"""

from flask_move_server.core.errors import MapNotReceived, NoMap


class FakeModes:
    """A mode manager that is always ``running`` in the mode it was told; publishes ``mode`` events."""

    runs_stack = True

    def __init__(self, events, mode="mapping", map_name=None):
        self.events = events
        self.calls = []
        self.poses = []  # the pose each switch was given
        self.mode, self.map = mode, map_name

    @property
    def active_map(self):
        return self.map if self.mode == "navigation" else None

    def status(self):
        return {"mode": self.mode, "map": self.map, "state": "running", "since": "2026-01-01T00:00:00+00:00",
                "message": None}

    def switch(self, mode, map_name=None, pose=None):
        self.calls.append(("switch", mode, map_name))
        self.poses.append(pose)
        self.mode, self.map = mode, map_name
        self.events.publish("mode", self.status())
        return self.status()


class FakeMapSource:
    """The live map: ``grid`` (None: nothing published) and a version bumped by :meth:`publish`."""

    def __init__(self, grid=None):
        self.grid = grid
        self.version = 1 if grid is not None else 0
        self.context = {"mode": "mapping", "map": None}
        self.decoded = 0

    def publish(self, grid):
        self.grid, self.version = grid, self.version + 1

    def held_version(self):
        if self.grid is None:
            raise NoMap("No map is published (fake).")
        return self.version

    def current(self):
        self.decoded += 1
        return self.held_version(), self.grid

    def latest(self, timeout):
        if self.grid is None:
            raise MapNotReceived("No map arrived within {:g} s: is mapping running?".format(timeout))
        return self.current()
