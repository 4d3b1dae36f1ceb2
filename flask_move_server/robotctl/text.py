"""What ``robotctl`` prints: the status summary, the waypoint table, the live progress line.

Pure text from the JSON the server answered, kept apart from the commands in
:mod:`flask_move_server.robotctl.cli` so the words and layout can change without touching how
requests are made (and be tested without a robot).
"""

import contextlib
import math
import sys
import unicodedata


def progress(name, nav):
    """The live line while a goal is under way: name, state, distance left."""
    distance = nav.get("distance_remaining")
    left = "distance unknown" if distance is None else "{:.2f} m to go".format(distance)
    return "{}: {}, {}".format(name, nav.get("state"), left)


class LiveLine:
    """One status line rewritten in place on a terminal, a line per change otherwise."""

    def __init__(self, stream):
        self._stream = stream
        self._tty = stream.isatty()
        self._last = None

    def show(self, text, key=None):
        """Show ``text``: in place on a terminal; otherwise as a new line when ``key`` changed (by default
        the text before its first comma, the state)."""
        key = text.split(",")[0] if key is None else key
        if self._tty:
            self._stream.write("\r\033[K" + text)
        elif self._last is None or key != self._last:
            self._stream.write(text + "\n")
        self._stream.flush()
        self._last = key

    def end(self):
        """Finish the line (before anything else is printed)."""
        if self._tty and self._last is not None:
            self._stream.write("\n")
            self._stream.flush()
        self._last = None


def describe_status(data, url):
    """The lines of ``robotctl status``."""
    ros = data.get("ros") or {}
    pose = data.get("pose")
    lines = ["robot:      {} (ROS {})".format(url, ros.get("state", "?"))]
    if data.get("mode"):
        lines.append("mode:       " + _describe_mode(data["mode"]))
    if pose:
        lines.append("pose:       {} in {}, {:.1f} s old ({})".format(
            xy_yaw(pose), pose.get("frame"), pose.get("age") or 0.0, pose.get("source", "tf")))
    else:
        lines.append("pose:       unknown (no tf map -> base_link, no /amcl_pose)")
    lines.append("navigation: " + _describe_navigation(data.get("navigation") or {}))
    lines.append("teleop:     " + _describe_teleop(data.get("teleop") or {}))
    motors = data.get("motors") or {}
    lines.append("motors:     {} left {:+.2f} right {:+.2f}".format(
        motors.get("backend", "?"), motors.get("left") or 0.0, motors.get("right") or 0.0))
    if "estop" in data:
        lines.append("e-stop:     " + _describe_estop(data["estop"] or {}))
    stuck = data.get("stuck") or {}
    if stuck.get("state", "free") != "free":
        lines.append("stuck:      " + (stuck.get("message") or stuck["state"]) + (
            " ('robotctl back-out' backs it out)" if stuck.get("waiting") else ""))
    dock = data.get("dock") or {}
    if dock.get("state", "undocked") != "undocked":
        lines.append("dock:       " + (dock.get("message") or dock["state"]))
    problem = (data.get("waypoints") or {}).get("problem")
    if problem:
        lines.append("waypoints:  PROBLEM: " + problem)
    return lines


def _describe_mode(mode):
    """``navigation on flat``, ``mapping (starting)``, ``idle``; a failed stack with why."""
    text = str(mode.get("mode"))
    if mode.get("mode") == "navigation":
        text += " on " + (mode["map"] if mode.get("map") else "the stack's own map")
    state = mode.get("state")
    if state == "failed":
        return "{} FAILED: {}".format(text, mode.get("message") or "see GET /mode")
    return text if state == "running" else "{} ({})".format(text, state)


def _describe_navigation(nav):
    state = nav.get("state", "idle")
    if state == "idle":
        return "idle"
    target = nav.get("target") or "({})".format(xy_yaw(nav.get("goal") or {}))
    text = "{} -> {}".format(state, target)
    if state in ("active", "stuck") and nav.get("distance_remaining") is not None:
        text += ", {:.2f} m to go".format(nav["distance_remaining"])
    return text


def _describe_estop(estop):
    if not estop.get("latched"):
        return "off"
    return "LATCHED by {} since {} ('robotctl estop release' lifts it)".format(
        estop.get("source") or "?", estop.get("since") or "?")


def _describe_teleop(teleop):
    if not teleop.get("active"):
        return "idle"
    return "{:+.2f} m/s, {:+.2f} rad/s for {:.1f} s more".format(
        teleop.get("linear", 0.0), teleop.get("angular", 0.0), teleop.get("remaining") or 0.0)


def xy_yaw(pose):
    """``x 1.00, y 2.00, yaw 0.50 rad (29 deg)`` of a pose or goal dict; ``?`` when missing."""
    if not pose:
        return "?"
    x, y, yaw = (round(pose.get(k, 0.0), 2) + 0.0 for k in ("x", "y", "yaw"))  # + 0.0: no "-0.00"
    degrees = round(math.degrees(pose.get("yaw", 0.0))) + 0.0
    return "x {:.2f}, y {:.2f}, yaw {:.2f} rad ({:.0f} deg)".format(x, y, yaw, degrees)


def waypoint_table(waypoints):
    """Aligned rows: name, x, y, yaw (rad and degrees)."""
    width = max(4, max(columns(wp["name"]) for wp in waypoints))
    rows = ["{}  {:>8}  {:>8}  {:>7}  {:>5}".format(padded("NAME", width), "X [m]", "Y [m]", "YAW", "[deg]")]
    for wp in waypoints:
        rows.append("{}  {:>8.2f}  {:>8.2f}  {:>7.2f}  {:>5.0f}".format(
            padded(wp["name"], width), wp["x"], wp["y"], wp["yaw"], math.degrees(wp["yaw"])))
    return rows


def tolerant_output():
    """Let a terminal that cannot show a name ("Küche" in an ASCII or Latin-1 locale) get ``K\\xfcche``
    rather than a crash: stdout's unencodable characters are escaped, as stderr's already are."""
    reconfigure = getattr(sys.stdout, "reconfigure", None)
    if reconfigure is not None:
        reconfigure(errors="backslashreplace")


def columns(text):
    """How many terminal columns ``text`` takes: a wide letter (台所) two, an accent that combines none."""
    return sum(0 if unicodedata.category(c) in ("Mn", "Me") else 2 if unicodedata.east_asian_width(c) in "WF" else 1
               for c in text)


def padded(text, width):
    """``text`` and the spaces that make it ``width`` terminal columns wide (names line up in any script)."""
    return text + " " * max(0, width - columns(text))


def rewritten(text, patterns):
    """``text`` with each ``(compiled pattern, replacement)`` applied: HTTP calls told as robotctl commands."""
    for pattern, words in patterns:
        text = pattern.sub(words, text)
    return text


@contextlib.contextmanager
def in_robotctl_words(rewrite, advice=None, name=None):
    """Around a request: a refusal whose code ``advice`` knows is told in its words (``{name}`` filled);
    any other is passed through ``rewrite`` (a text → text function), and re-raised as it was when
    that changes nothing."""
    from flask_move_server.core.errors import ClientError

    try:
        yield
    except ClientError as exc:
        code = (getattr(exc, "body", None) or {}).get("error")
        if advice and code in advice:
            raise ClientError(advice[code].format(name=name), exc.exit_status) from None
        said = rewrite(str(exc))
        if said == str(exc):
            raise
        raise ClientError(said, exc.exit_status) from None
