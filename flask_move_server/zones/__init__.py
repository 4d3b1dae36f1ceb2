"""Zones: where the robot must not go, drawn by its owner on one map.

A zone is a *keepout* polygon (the cot, the cat's bowls, the rug that jams the wheels) or a
*wall*, a polyline ``WALL_THICKNESS`` thick (across the top of the stairs, a doorway), and is
``enabled`` or not (today the robot may go there). Kept per map in its waypoints file::

    zones:
      Katzenecke: {kind: keepout, polygon: [[2.0, 1.0], [3.0, 1.0], [3.0, 2.0]], enabled: true}
      stairs: {kind: wall, line: [[4.0, 0.0], [4.0, 1.5]], enabled: false}

:func:`make_zone` checks one entry as the API and the file give it: a name by the rule of every
name, a known kind, finite coordinates, ``MIN_POINTS``..``MAX_POINTS`` corners, a polygon that
does not cross itself and covers at least ``MIN_AREA``, a wall at least ``MIN_LENGTH`` long.
:func:`distance` (0 inside) is what goals are judged by. Pure: no rospy, no numpy.
"""

import hashlib
import math
from dataclasses import dataclass
from typing import Tuple

from flask_move_server.core import names
from flask_move_server.core.errors import BadZone, shown

TOPIC = "keepout_map"  # where the server publishes the mask the costmaps' keepout_layer reads (ros/keepout.py)
KINDS = {"keepout": "polygon", "wall": "line"}  # kind -> the field holding its points
MIN_POINTS = {"keepout": 3, "wall": 2}
MAX_POINTS = 100  # corners of one zone: a room's outline has tens, never hundreds
MAX_ZONES = 100  # zones of one map (Valetudo's owners use under ten)
COORDINATE_LIMIT = 10000.0  # m: far beyond any building; the map's own bounds are checked by the API
MIN_AREA = 0.01  # m²: 10 x 10 cm, about four cells of a 5 cm map
MIN_LENGTH = 0.05  # m: a wall shorter than a cell is not a wall
WALL_THICKNESS = 0.1  # m: two cells of a 5 cm map, so no 8-connected path slips between its cells
FIELDS = {"kind", "polygon", "line", "enabled"}


@dataclass(frozen=True)
class Zone:
    """One zone of a map: ``points`` are (x, y) in the map frame, a polygon's corners or a wall's line."""

    name: str
    kind: str
    points: Tuple[Tuple[float, float], ...]
    enabled: bool = True

    def as_dict(self):
        """The zone as the API and the file show it."""
        return {"kind": self.kind, KINDS[self.kind]: [list(p) for p in self.points], "enabled": self.enabled}

    def switched(self, enabled):
        """This zone, enabled or not."""
        return Zone(self.name, self.kind, self.points, bool(enabled))

    def renamed(self, name):
        return Zone(name, self.kind, self.points, self.enabled)

    def bounds(self):
        """(min x, min y, max x, max y) of its points, a wall's thickness included."""
        pad = WALL_THICKNESS / 2 if self.kind == "wall" else 0.0
        xs, ys = [p[0] for p in self.points], [p[1] for p in self.points]
        return min(xs) - pad, min(ys) - pad, max(xs) + pad, max(ys) + pad


def zone_object_id(name):
    """The zone's id in MQTT topics and Home Assistant: ``zone_`` and 10 hex digits of its name's hash (a name in
    any language is not a topic level; the same name always gives the same id)."""
    return "zone_" + hashlib.sha1(name.encode("utf-8")).hexdigest()[:10]


def check_zone_name(name):
    """``name`` in NFC if it is a valid zone name (the rule of every name), else BadZone."""
    return names.checked(name, "zone name", BadZone)


def make_zone(name, entry):
    """The Zone ``name`` of ``entry`` (``{"kind", "polygon" or "line", "enabled"}``); BadZone naming what is wrong."""
    name = check_zone_name(name)
    if not isinstance(entry, dict):
        raise BadZone("A zone is an object: {\"kind\": \"keepout\", \"polygon\": [[x, y], ...]} or "
                      "{\"kind\": \"wall\", \"line\": [[x, y], ...]}.")
    unknown = sorted(str(key) for key in entry if key not in FIELDS)
    if unknown:
        raise BadZone("Unknown field {} in the zone: use kind, polygon (keepout), line (wall) and enabled.".format(
            shown(unknown[0])))
    kind = entry.get("kind")
    if kind not in KINDS:
        raise BadZone("kind must be \"keepout\" (a polygon the robot keeps out of) or \"wall\" (a line it never "
                      "crosses).")
    field = KINDS[kind]
    other = KINDS["wall" if kind == "keepout" else "keepout"]
    if other in entry:
        raise BadZone("A {} zone has {}, not {}.".format(kind, field, other))
    enabled = entry.get("enabled", True)
    if not isinstance(enabled, bool):
        raise BadZone("enabled must be true or false.")
    points = _points(field, entry.get(field), MIN_POINTS[kind])
    if kind == "keepout":
        points = _polygon(points)
    else:
        points = _line(points)
    return Zone(name, kind, points, enabled)


def _points(field, raw, least):
    if not isinstance(raw, list):
        raise BadZone("{} must be a list of [x, y] points in metres, in the map's frame.".format(field))
    if not least <= len(raw) <= MAX_POINTS:
        raise BadZone("{} needs {} to {} points, got {}.".format(field, least, MAX_POINTS, len(raw)))
    points = []
    for i, point in enumerate(raw):
        if not (isinstance(point, list) and len(point) == 2 and all(_finite(v) for v in point)):
            raise BadZone("{}[{}] must be [x, y], two finite numbers of metres within ±{:.0f}.".format(
                field, i, COORDINATE_LIMIT))
        points.append((float(point[0]), float(point[1])))
    return points


def _finite(value):
    return (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
            and abs(value) <= COORDINATE_LIMIT)


def _polygon(points):
    if len(points) > 3 and points[0] == points[-1]:
        points = points[:-1]  # written closed: the last corner is the first
    if len(set(points)) != len(points):
        raise BadZone("polygon has the same corner twice: each corner once, in order around it.")
    edges = list(zip(points, points[1:] + points[:1]))
    n = len(edges)
    for i, a in enumerate(edges):
        for j in range(i + 2, n - (1 if i == 0 else 0)):  # not its neighbours: they share a corner
            if _segments_cross(a, edges[j]):
                raise BadZone("polygon crosses itself (its edges {} and {} cross): give the corners in order "
                              "around it.".format(i + 1, j + 1))
    if abs(_area(points)) < MIN_AREA:
        raise BadZone("polygon covers {:.4f} m²; a zone covers at least {:g} m² (10 x 10 cm).".format(
            abs(_area(points)), MIN_AREA))
    return tuple(points)


def _line(points):
    for i, (a, b) in enumerate(zip(points, points[1:])):
        if a == b:
            raise BadZone("line has the same point twice in a row (points {} and {}).".format(i, i + 1))
    length = sum(math.dist(a, b) for a, b in zip(points, points[1:]))
    if length < MIN_LENGTH:
        raise BadZone("line is {:.3f} m long; a wall is at least {:g} m.".format(length, MIN_LENGTH))
    return tuple(points)


def _area(points):
    return sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(points, points[1:] + points[:1])) / 2.0


def _segments_cross(s, t):
    """True when segments ``s`` and ``t`` meet (touching counts)."""
    (p1, p2), (p3, p4) = s, t
    d1, d2 = _side(p3, p4, p1), _side(p3, p4, p2)
    d3, d4 = _side(p1, p2, p3), _side(p1, p2, p4)
    if ((d1 > 0) != (d2 > 0)) and d1 and d2 and ((d3 > 0) != (d4 > 0)) and d3 and d4:
        return True
    return any(d == 0 and _on_segment(a, b, p) for d, a, b, p in
               ((d1, p3, p4, p1), (d2, p3, p4, p2), (d3, p1, p2, p3), (d4, p1, p2, p4)))


def _side(a, b, p):
    return (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])


def _on_segment(a, b, p):
    return min(a[0], b[0]) <= p[0] <= max(a[0], b[0]) and min(a[1], b[1]) <= p[1] <= max(a[1], b[1])


# judging a point ----------------------------------------------------------------------------------

def inside_polygon(points, x, y):
    """Even-odd rule: True when (x, y) lies inside the polygon ``points``."""
    inside = False
    for (x1, y1), (x2, y2) in zip(points, points[1:] + points[:1]):
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


def distance(zone, x, y):
    """Metres from (x, y) to what ``zone`` keeps the robot out of (0 inside a keepout or within a wall)."""
    points = list(zone.points)
    if zone.kind == "keepout":
        if inside_polygon(points, x, y):
            return 0.0
        edges = zip(points, points[1:] + points[:1])
        return min(_to_segment(x, y, a, b) for a, b in edges)
    nearest = min(_to_segment(x, y, a, b) for a, b in zip(points, points[1:]))
    return max(0.0, nearest - WALL_THICKNESS / 2)


def _to_segment(x, y, a, b):
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0 else max(0.0, min(1.0, ((x - a[0]) * dx + (y - a[1]) * dy) / length2))
    return math.hypot(x - a[0] - t * dx, y - a[1] - t * dy)


def blocking(zones, x, y, clearance):
    """The first enabled zone of ``zones`` nearer than ``clearance`` m to (x, y) (inside it: 0), or None."""
    for zone in zones:
        if zone.enabled and distance(zone, x, y) < clearance:
            return zone
    return None
