"""What the zones of the active map allow: goals outside them, and a robot never trapped inside one.

:class:`ZoneGuard` refuses a goal (a place, a route's stop, the staging pose before the dock)
whose pose lies inside an enabled zone or nearer to it than ``clearance``, the robot's inscribed
radius: there move_base's costmap holds the zone's lethal cells or their inscribed inflation, and
navfn would fail to plan after the robot had been told the goal was taken. It refuses before
move_base is asked, naming the zone (409 ``in_zone``).

:meth:`ZoneGuard.holding` is the robot-inside-a-zone rule (docs/zones.md): an enabled zone that
the robot's body touches now (nearer than ``reach``, its circumscribed radius) is left out of the
mask the costmaps read until the robot has left it by ``HYSTERESIS`` more, so switching a zone on
around the robot, or driving into one with the joystick, never makes it stand in lethal cells of
its own making (Nav2's KeepoutFilter leaves it stuck there). Goals into that zone are still refused.
Pure: no rospy.
"""

import threading

from flask_move_server.core.errors import InZone, shown
from flask_move_server.zones import blocking, distance

HYSTERESIS = 0.05  # m further out than its reach before a zone the robot stood in holds again


class ZoneGuard:
    """The enabled zones of the store's map, judged against goals and the robot's pose."""

    def __init__(self, store, clearance, reach):
        """``clearance``: inscribed radius (goals); ``reach``: circumscribed radius (the robot inside)."""
        self.store = store
        self.clearance = clearance
        self.reach = reach
        self._lock = threading.Lock()
        self._held = frozenset()  # names of the zones left out of the mask while the robot is in them

    def check(self, pose, target=None):
        """InZone when ``pose`` (x, y) lies in or too near an enabled zone; the message names it."""
        zone = blocking(self.store.zones(), pose.x, pose.y, self.clearance)
        if zone is None:
            return
        what = "The place {}".format(shown(target)) if target else "The goal ({:.2f}, {:.2f})".format(pose.x, pose.y)
        where = "in" if distance(zone, pose.x, pose.y) == 0 else "too near (the robot would touch it)"
        raise InZone("{} lies {} the zone {}, which the robot keeps out of. Switch the zone off first "
                     "(PATCH /zones/{} {{\"enabled\": false}}) or choose a place outside it.".format(
                         what, where, shown(zone.name), zone.name))

    def blocks(self, zone, x, y):
        """True when an enabled ``zone`` keeps the robot's centre off (x, y)."""
        return zone.enabled and distance(zone, x, y) < self.clearance

    @property
    def held(self):
        """Names of the zones left out of the mask as last judged (:meth:`holding`)."""
        with self._lock:
            return self._held

    def holding(self, pose):
        """Names of the enabled zones left out of the mask now, the robot at ``pose`` (None: not known)."""
        with self._lock:
            if pose is None:
                return self._held
            held = set()
            for zone in self.store.zones():
                if not zone.enabled:
                    continue
                gap = distance(zone, pose.x, pose.y)
                if gap < self.reach or (zone.name in self._held and gap < self.reach + HYSTERESIS):
                    held.add(zone.name)
            self._held = frozenset(held)
            return self._held
