"""``robotctl map …``: the robot's maps from a terminal (``save``, ``list``, ``rm``).

``map save`` sends ``POST /maps`` with a request timeout long enough for the
server to wait ``maps.save_timeout`` for a map and write a large one. The mode
commands (``map start``, ``map use``) and ``map explore`` (robotctl/explore.py)
join the same ``map`` parser.
"""

import sys

from flask_move_server.robotctl import explore as client_explore
from flask_move_server.robotctl import modes as client_modes
from flask_move_server.robotctl.api import ExitStatus, name_path
from flask_move_server.robotctl.text import columns, in_robotctl_words, padded

SAVE_TIMEOUT = 60.0  # s: the server waits up to maps.save_timeout (10 s) for a map, then writes it


def map_path(name):
    """The API path of map ``name`` (spaces and the like escaped)."""
    return name_path("/maps/", name)


def cmd_map(client, args):
    """Dispatch ``robotctl map ACTION``."""
    return ACTIONS[args.action or "list"](client, args)


def cmd_save(client, args):
    body = {"name": args.name}
    if args.overwrite:
        body["overwrite"] = True
    if args.then_navigate:
        body["then"] = "navigation"
    with _in_robotctl_words(args.name):
        answer = client.request("POST", "/maps", body, timeout=max(client.timeout, SAVE_TIMEOUT))
    info = answer.get("map") or {}
    _say("saved map {} ({}{}).".format(args.name, _size(info), _places(answer, info)))
    if "mode_error" in answer:
        _say("robotctl: saved, but not switched to it: {}".format(answer["mode_error"].get("message")), sys.stderr)
        return ExitStatus.ERROR
    if args.then_navigate:
        _say("switching to navigation on {} ('robotctl status' follows it).".format(args.name))
    return ExitStatus.OK


def _places(answer, info):
    """What the saved map's places are: a copy of the waypoints file's, or those marked while mapping."""
    if answer.get("adopted_waypoints"):
        return ", with a copy of the waypoints"
    count = info.get("waypoints") or 0
    return ", with the {} place{} marked while mapping".format(count, "" if count == 1 else "s") if count else ""


def cmd_list(client, args):
    answer = client.get("/maps")
    maps = answer.get("maps") or []
    if not maps:
        _say("no maps saved yet: 'robotctl map start', drive around, then 'robotctl map save NAME'.")
        return ExitStatus.OK
    for line in map_table(maps, answer.get("active")):
        _say(line)
    return ExitStatus.OK


def cmd_rm(client, args):
    with _in_robotctl_words(args.name):
        client.delete(map_path(args.name))
    _say("removed map {} (its image and waypoints too).".format(args.name))
    return ExitStatus.OK


# The server's refusals that name an HTTP field or route, said with robotctl's own commands.
_ADVICE = {
    "map_exists": "a map named {name} is saved already: 'robotctl map save {name} --overwrite' replaces it, "
                  "or pick another name",
    "map_in_use": "{name} is the map in use: switch to another first ('robotctl map use OTHER', or "
                  "'robotctl map start' to map again)",
    "map_configured": "{name} is the map the robot's stack was configured with, not a saved map: it cannot be "
                      "removed or renamed",
}


def _in_robotctl_words(name):
    """Around a map request: a refusal the table above knows is told in robotctl's words."""
    return in_robotctl_words(_rewrite, _ADVICE, name)


def _rewrite(text):
    return text.replace("GET /maps lists the saved maps", "'robotctl map list' lists them")


ACTIONS = {"save": cmd_save, "list": cmd_list, "rm": cmd_rm, "start": client_modes.cmd_map,
           "use": client_modes.cmd_map, "explore": client_explore.cmd_explore}


def map_table(maps, active=None):
    """Aligned rows: name (``*`` for the map in use), size in metres, waypoints, last change."""
    width = max(4, max(columns(m["name"]) for m in maps))
    rows = ["  {}  {:>15}  {:>9}  {}".format(padded("NAME", width), "SIZE [m]", "WAYPOINTS", "MODIFIED")]
    for m in maps:
        mark = "*" if m["name"] == active else " "
        size = m.get("problem") and "broken" or _size(m)
        when = m.get("modified", "") + (" (configured)" if m.get("source") == "configured" else "")
        rows.append("{} {}  {:>15}  {:>9}  {}".format(mark, padded(m["name"], width), size, m.get("waypoints", 0),
                                                       when))
    return rows


def _size(info):
    if not info.get("width") or not info.get("resolution"):
        return "size unknown"
    return "{:.1f} x {:.1f}".format(info["width"] * info["resolution"], info["height"] * info["resolution"])


def add_parser(sub, positive):
    """``robotctl map start|explore|use|save|list|rm`` on robotctl's subcommand parser ``sub``."""
    p = sub.add_parser("map", help="the robot's maps: start (mapping), explore, save, list, use, rm")
    p.set_defaults(run=cmd_map, action="list")
    actions = p.add_subparsers(dest="action", metavar="ACTION")
    client_modes.add_map_actions(actions, positive)
    client_explore.add_action(actions, positive)
    save = actions.add_parser("save", help="save the map being made as NAME (in mapping mode)")
    save.add_argument("name")
    save.add_argument("--overwrite", action="store_true", help="replace a map saved under NAME")
    save.add_argument("--then-navigate", action="store_true", help="then navigate on it (switch mode)")
    actions.add_parser("list", help="the saved maps; * marks the one in use")
    rm = actions.add_parser("rm", help="delete map NAME with its image and waypoints")
    rm.add_argument("name")
    return p


def _say(text, stream=None):
    print(text, file=stream or sys.stdout, flush=True)
