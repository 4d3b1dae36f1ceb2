"""``robotctl doctor``: the first-boot checks, one line each, with what to do when one is not a pass.

Calls ``GET /diagnostics`` (``--box`` adds the box-ahead test of the laser's yaw, ``--seconds``
how long the robot listens). Exit 0 when nothing fails (warnings included), 1 when a check fails.
"""

import sys

from flask_move_server.robotctl.api import ExitStatus, dumps

MARKS = {"pass": "PASS", "warn": "WARN", "fail": "FAIL", "skip": "skip"}


def add_parser(sub, positive):
    p = sub.add_parser("doctor", help="first-boot checks: lidar, tf, odometry, navigation, the Pi")
    p.add_argument("--box", action="store_true",
                   help="also the laser-yaw test: put a box about 1 m straight ahead of the robot first")
    p.add_argument("--seconds", type=positive, default=None, metavar="S",
                   help="listen to /scan and /odom for S seconds (0.5-10; default: the robot's diagnostics.window)")
    p.add_argument("--json", action="store_true", help="the raw JSON of GET /diagnostics")
    p.set_defaults(run=cmd_doctor)


def cmd_doctor(client, args):
    """Print the robot's report; exit 1 when any check fails."""
    query = ["box=1"] if args.box else []
    if args.seconds is not None:
        query.append("seconds={:g}".format(args.seconds))
    path = "/diagnostics" + ("?" + "&".join(query) if query else "")
    report = client.request("GET", path, timeout=client.timeout + (args.seconds or 10.0))
    if args.json:
        _say(dumps(report))
    else:
        for line in describe(report):
            _say(line)
    return ExitStatus.ERROR if report.get("status") == "fail" else ExitStatus.OK


def describe(report):
    """The report as lines: one per check, the advice indented under it, then the verdict."""
    width = max((len(c["name"]) for c in report["checks"]), default=0)
    lines = []
    for check in report["checks"]:
        lines.append("{}  {}  {}".format(MARKS.get(check["level"], check["level"]), check["name"].ljust(width),
                                         check["summary"]))
        if check.get("advice") and check["level"] != "pass":
            lines.append("      {}  -> {}".format(" " * width, check["advice"]))
    counts = {level: sum(c["level"] == level for c in report["checks"]) for level in ("fail", "warn")}
    lines.append("{}: {} failed, {} warning{}{}".format(
        report["status"].upper(), counts["fail"], counts["warn"], "" if counts["warn"] == 1 else "s",
        "" if report["status"] == "fail" else " (fix warnings when you can)" if counts["warn"] else ""))
    return lines


def _say(text):
    print(text, file=sys.stdout, flush=True)
