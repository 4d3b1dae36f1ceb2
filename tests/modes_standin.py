"""A navigation-stack backend for the mode manager's tests: it "starts" in a thread-safe way,
can be held while starting, made to fail, or made to die by itself later.

The real backends (modes/launched.py: roslaunch children; modes/simulated.py: the sim) are
tested with real processes and the real sim; this one lets the manager's rules (one switch at a
time, restarts with back-off, what is remembered) be tested without waiting on either.
"""

import os
import threading

from flask_move_server.core.errors import StackFailed
from flask_move_server.maps import mapfile


class StandInStack:
    """Records ``("start", mode, yaml)`` / ``("stop",)`` / ``("close",)`` in ``calls``."""

    def __init__(self):
        self.calls = []
        self.failures = []  # messages: the next starts raise StackFailed with these, in order
        self.gate = threading.Event()
        self.gate.set()  # clear it to hold a start until it is set again
        self.starting = threading.Event()
        self.on_exit = None
        self._threads = []

    def start(self, mode, map_yaml, on_exit):
        self.calls.append(("start", mode, map_yaml))
        self.starting.set()
        self.gate.wait(10)
        if self.failures:
            raise StackFailed(self.failures.pop(0))
        self.on_exit = on_exit

    def stop(self):
        self.calls.append(("stop",))
        self.on_exit = None

    def close(self):
        self.calls.append(("close",))

    def die(self, message):
        """The running stack stops by itself: the manager hears it from another thread, as from a real one."""
        on_exit = self.on_exit
        thread = threading.Thread(target=on_exit, args=(message,), name="stand-in exit")
        thread.start()
        self._threads.append(thread)
        thread.join(5)

    def starts(self):
        return [c[1:] for c in self.calls if c[0] == "start"]


def save_map(config, name, waypoints=None):
    """A small saved map in the config's maps folder (and its waypoints file, when given)."""
    folder = config.maps_folder()
    os.makedirs(folder, exist_ok=True)
    grid = mapfile.Grid(4, 3, 0.05, -0.1, -0.1, bytes(12))
    mapfile.save(folder, name, grid)
    if waypoints is not None:
        with open(os.path.join(folder, name + ".waypoints.yaml"), "w", encoding="utf-8") as f:
            f.write(waypoints)
    return os.path.join(folder, name + ".yaml")
