"""``robotctl zone list|add|enable|disable|rm``: the active map's no-go zones and virtual walls (/zones).

``add NAME --keepout X,Y X,Y X,Y ...`` (a polygon's corners) or ``--wall X,Y X,Y ...`` (a line);
``--disabled`` saves it switched off. Coordinates are metres in the map's frame (docs/zones.md).
"""

from flask_move_server.core.errors import ClientError
from flask_move_server.robotctl.api import ExitStatus, name_path


def cmd_zone_list(client, args):
    zones = (client.get("/zones") or {}).get("zones") or []
    if not zones:
        print("no zones on this map (robotctl zone add NAME --keepout X,Y X,Y X,Y ...)")
    for zone in zones:
        print(describe(zone))
    return ExitStatus.OK


def describe(zone):
    """One line: name, kind, points, on or off (and waiting while the robot stands in it)."""
    points = zone.get("polygon") or zone.get("line") or []
    state = "on" if zone.get("enabled") else "off"
    if zone.get("waiting"):
        state = "on, waiting for the robot to leave it"
    kind = "keep out" if zone.get("kind") == "keepout" else "wall"
    return "{}  {} {}  ({})".format(zone.get("name"), kind, " ".join("{:g},{:g}".format(*p) for p in points), state)


def cmd_zone_add(client, args):
    kind, field, raw = ("keepout", "polygon", args.keepout) if args.keepout else ("wall", "line", args.wall)
    body = {"kind": kind, field: [_point(text) for text in raw], "enabled": not args.disabled}
    zone = (client.put(name_path("/zones/", args.name), body) or {}).get("zone") or {}
    print("saved: " + describe(zone))
    return ExitStatus.OK


def _point(text):
    try:
        x, y = (float(v) for v in text.split(","))
    except ValueError:
        raise ClientError("{!r} is not a point: write X,Y in metres, e.g. 2.0,1.5".format(text), ExitStatus.USAGE)
    return [x, y]


def _switch(enabled):
    def run(client, args):
        zone = (client.patch(name_path("/zones/", args.name), {"enabled": enabled}) or {}).get("zone") or {}
        print(describe(zone))
        return ExitStatus.OK
    return run


def cmd_zone_rm(client, args):
    client.delete(name_path("/zones/", args.name))
    print("deleted the zone {}".format(args.name))
    return ExitStatus.OK


def add_parsers(sub):
    """``robotctl zone ...`` on robotctl's subcommand parser ``sub``."""
    zone = sub.add_parser("zone", help="no-go zones and virtual walls of the map in use")
    verbs = zone.add_subparsers(dest="verb", metavar="list|add|enable|disable|rm")
    verbs.required = True
    verbs.add_parser("list", help="list the zones").set_defaults(run=cmd_zone_list)
    add = verbs.add_parser("add", help="add or replace a zone")
    add.add_argument("name")
    shape = add.add_mutually_exclusive_group(required=True)
    shape.add_argument("--keepout", nargs="+", metavar="X,Y", help="the corners of a no-go zone, in order")
    shape.add_argument("--wall", nargs="+", metavar="X,Y", help="the points of a virtual wall")
    add.add_argument("--disabled", action="store_true", help="save it switched off")
    add.set_defaults(run=cmd_zone_add)
    for verb, enabled, text in (("enable", True, "the robot keeps out again"),
                                ("disable", False, "today the robot may go there")):
        p = verbs.add_parser(verb, help=text)
        p.add_argument("name")
        p.set_defaults(run=_switch(enabled))
    rm = verbs.add_parser("rm", help="delete a zone")
    rm.add_argument("name")
    rm.set_defaults(run=cmd_zone_rm)
