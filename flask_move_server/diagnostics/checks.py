"""The first-boot doctor's checks: each turns what was observed into one line, pass / warn / fail / skip.

Pure: the observations come in as plain values (``RosObservations`` from ``ros/observe.py``,
``HostReadings`` from ``diagnostics/host.py``); every check says what it saw and, when it is not
a pass, what the owner does about it. The order is the order to fix things in on a new robot:
the lidar, the frames, the odometry, the navigation stack, then the Pi itself.
"""

import math
from dataclasses import asdict, dataclass
from typing import List, Optional, Tuple

PASS, WARN, FAIL, SKIP = "pass", "warn", "fail", "skip"
SCAN_MIN_RATE = 4.0      # Hz: an A1 spins at 5.5-10 Hz; slower means a tired motor or a lost USB link
ODOM_MIN_RATE = 10.0     # Hz: the drive publishes 20 (drive.odom_rate); AMCL and DWA want it smooth
TF_MAX_AGE = 1.0         # s: a moving transform older than this has stopped
AMCL_LOST_M = 1.0        # m of AMCL's standard deviation at which the robot is as good as lost
AMCL_UNSURE_M = 0.3
AMCL_UNSURE_RAD = 0.5
BOX_RANGE = (0.2, 2.5)   # m: where the box of the box-ahead test is looked for
BOX_AHEAD = math.radians(30)


@dataclass
class Check:
    """One line of the doctor's report."""

    name: str
    level: str
    summary: str
    advice: str = ""

    def as_dict(self):
        return asdict(self)


@dataclass
class TopicSample:
    """Messages seen on one topic during the observation window."""

    count: int = 0
    rate: float = 0.0         # Hz over the window (0 with fewer than two messages)
    age: Optional[float] = None  # s between the last message's stamp and now (clock skew shows here)


@dataclass
class ScanSample(TopicSample):
    frame: str = ""
    range_max: float = 0.0
    nearest: Optional[Tuple[float, float]] = None  # (range m, angle rad in the scan's frame) in BOX_RANGE


@dataclass
class TfLink:
    """One link of the tf tree: found or not, and how old (None for a static link)."""

    parent: str
    child: str
    found: bool
    age: Optional[float] = None
    yaw: float = 0.0


@dataclass
class RosObservations:
    """What the doctor saw of ROS in one window."""

    connected: bool
    mode: Optional[str]          # idle | mapping | navigation, or None when this server runs no stack
    scan: ScanSample
    odom: TopicSample
    links: List[TfLink]
    move_base: bool
    amcl_publishers: int
    amcl_spread: Optional[Tuple[float, float, float]]  # std dev x (m), y (m), yaw (rad) of /amcl_pose
    scan_match: Optional[Tuple[float, int]] = None  # (share, points) of scan_match.match_share, None: not matched


def overall(checks):
    """fail if any check fails, else warn if any warns, else pass."""
    levels = {c.level for c in checks}
    return FAIL if FAIL in levels else WARN if WARN in levels else PASS


BOX_HINT = ("Put a box about 1 m straight ahead of the robot, with nothing else within about 1.5 m in any "
            "direction (behind included), and run the box test (robotctl doctor --box, or the Health panel's button).")
SIM_BOX_HINT = ("The simulated lidar is mounted right (yaw pi, as docs/deploy.md mounts an A1): for its box test, "
                "turn the robot to face a wall about 1 m away (the page's Pose, or POST /pose) and run it again.")


def ros_checks(obs, box=False, simulated=False):
    """Every ROS check, in the order to fix things on a new robot (``simulated``: the sim's own lidar)."""
    if not obs.connected:
        return [Check("ros", FAIL, "no ROS master answers", "Start roscore (sudo systemctl start roscore) "
                      "and check ROS_MASTER_URI; GET /health says when the server is connected.")]
    checks = [scan_check(obs.scan), range_check(obs.scan), tf_check(obs.links, obs.mode), odom_check(obs.odom),
              move_base_check(obs), amcl_check(obs), localization_check(obs), scan_match_check(obs)]
    checks.append(box_check(obs, simulated) if box else Check(
        "laser_yaw", SKIP, "laser yaw {:.2f} rad (base_link -> {}): only a box ahead can prove it".format(
            laser_link(obs).yaw if laser_link(obs) else 0.0, obs.scan.frame or "laser"),
        SIM_BOX_HINT if simulated else BOX_HINT))
    return checks


def scan_check(scan):
    return _rate_check("scan", scan, SCAN_MIN_RATE, "5.5-10",
                       "Is the lidar plugged in and spinning? ls -l /dev/ttyUSB*; journalctl -u flask-move-server "
                       "| grep -i rplidar; docs/deploy.md, Troubleshooting: No /scan.",
                       "A slow lidar motor (a weak USB port: use a powered hub) or a busy Pi.",
                       " in frame {}".format(scan.frame))


def _rate_check(topic, sample, minimum, expected, advice_none, advice_slow, detail=""):
    """A topic that must arrive: fail when nothing came, warn below ``minimum`` Hz."""
    if sample.count == 0:
        return Check(topic, FAIL, "no /{} arrived".format(topic), advice_none)
    if sample.rate < minimum:
        return Check(topic, WARN, "/{} at {:.1f} Hz, expected {}".format(topic, sample.rate, expected), advice_slow)
    return Check(topic, PASS, "/{} at {:.1f} Hz{}".format(topic, sample.rate, detail))


def range_check(scan):
    if scan.count == 0:
        return Check("scan_range", SKIP, "no scan to read range_max from")
    if not scan.range_max > 0.5:
        return Check("scan_range", FAIL, "/scan says range_max = {:g}: AMCL ignores every such scan".format(
            scan.range_max), "rplidar_ros's SDK 2.0 with A1 firmware older than 1.24: update rplidar_ros to its "
                             "current master or dev-ros1 (Slamtec's SDK update of August 2023); set no scan mode.")
    return Check("scan_range", PASS, "range_max {:g} m".format(scan.range_max))


def tf_check(links, mode=None):
    """The chain map -> odom -> base_link -> laser: each link there, the moving ones fresh.

    In idle nobody publishes map -> odom (AMCL and gmapping are not running): a new robot, which
    starts idle, failed its first check for it. The chain checked then starts at odom."""
    if mode == "idle" and links:
        return _tf_chain_check(links[1:], " ({} -> {} is not expected in idle mode)".format(
            links[0].parent, links[0].child), first=1)
    return _tf_chain_check(links, "")


def _tf_chain_check(links, note, first=0):
    """``links`` from the ``first`` link of the whole chain on (it picks who publishes each)."""
    chain = " -> ".join([links[0].parent] + [link.child for link in links]) if links else ""
    missing = [(i, link) for i, link in enumerate(links) if not link.found]
    stale = [(i, link) for i, link in enumerate(links) if link.found and link.age is not None and link.age > TF_MAX_AGE]
    if missing:
        names = ", ".join("{} -> {}".format(link.parent, link.child) for _, link in missing)
        index, link = missing[0]
        return Check("tf", FAIL, "tf {} is missing {}".format(chain, names), _tf_advice(first + index, link))
    if stale:
        names = ", ".join("{} -> {} ({:.1f} s old)".format(link.parent, link.child, link.age) for _, link in stale)
        index, link = stale[0]
        return Check("tf", WARN, "tf {}: stale {}".format(chain, names), _tf_advice(first + index, link))
    return Check("tf", PASS, "tf {}{}".format(chain, note))


TF_PUBLISHERS = (
    "AMCL in navigation or gmapping in mapping publishes it: is the mode running (GET /mode)?",
    "the server's drive publishes it (drive.backend, drive.publish_tf): is the base driver up?",
    "the launch files' static transform (ROBOT_LASER_X/Y/Z/YAW in ros.env, numbers only).",
)


def _tf_advice(index, link):
    return "{} -> {}: {}".format(link.parent, link.child, TF_PUBLISHERS[min(index, 2)])


def odom_check(odom):
    return _rate_check("odom", odom, ODOM_MIN_RATE, "20 (drive.odom_rate)",
                       "The base driver publishes it: drive.backend must not be none unless another node drives "
                       "the base; robotctl status shows the motors.",
                       "A busy Pi (see the load line) or a slow serial base.")


def move_base_check(obs):
    if obs.move_base:
        return Check("move_base", PASS, "move_base answers goals")
    if obs.mode == "idle":
        return Check("move_base", SKIP, "move_base is not expected in idle mode")
    if obs.mode == "mapping":  # mapping.launch runs it (exploring, /goto while mapping) unless move_base:=false
        return Check("move_base", WARN, "move_base does not answer while mapping: the robot can be driven by "
                     "joystick, but it cannot explore or take goals", "mapping.launch starts move_base unless "
                     "it was given move_base:=false; journalctl -u flask-move-server shows why it stopped.")
    return Check("move_base", FAIL, "move_base does not answer", "Is navigation running (robotctl status, "
                 "GET /mode)? journalctl -u flask-move-server shows why the stack stopped.")


def amcl_check(obs):
    if obs.mode in ("idle", "mapping"):
        return Check("amcl", SKIP, "AMCL is not expected in {} mode".format(obs.mode))
    if obs.amcl_publishers == 0:
        return Check("amcl", FAIL, "nobody publishes /amcl_pose: AMCL is not running",
                     "Switch to navigation on a saved map (robotctl map use NAME).")
    return Check("amcl", PASS, "AMCL is running")


def localization_check(obs):
    if obs.mode in ("idle", "mapping") or obs.amcl_publishers == 0:
        return Check("localization", SKIP, "no AMCL estimate to judge")
    if obs.amcl_spread is None:
        return Check("localization", WARN, "AMCL has not published an estimate yet",
                     "Set the robot's pose (robotctl pose NAME, or RViz's 2D Pose Estimate) and drive a little.")
    sx, sy, syaw = obs.amcl_spread
    spread = max(sx, sy)
    text = "AMCL's estimate: +-{:.2f} m, +-{:.0f} deg".format(spread, math.degrees(syaw))
    advice = "Tell AMCL where the robot is (robotctl pose NAME or X Y YAW) and drive a little until it is sure."
    if spread > AMCL_LOST_M:
        return Check("localization", FAIL, text + ": the robot is lost", advice)
    if spread > AMCL_UNSURE_M or syaw > AMCL_UNSURE_RAD:
        return Check("localization", WARN, text + ": unsure", advice)
    return Check("localization", PASS, text)


def laser_link(obs):
    """The base_link -> laser link of the observed chain (None when the scan is in base_link itself)."""
    return obs.links[-1] if obs.links and obs.links[-1].child == obs.scan.frame else None


def box_check(obs, simulated=False):
    """Where the nearest thing within reach shows, in base_link: a box put 1 m ahead must show ahead."""
    if obs.scan.nearest is None:
        return Check("laser_yaw", FAIL, "nothing within {:g}-{:g} m of the lidar".format(*BOX_RANGE),
                     SIM_BOX_HINT if simulated else BOX_HINT)
    link = laser_link(obs)
    yaw = link.yaw if link else 0.0
    distance, angle = obs.scan.nearest
    bearing = _angle(angle + yaw)
    degrees = int(round(math.degrees(bearing))) or 0  # no "-0 deg"
    where = "the nearest thing, {:.2f} m away, shows at {:+d} deg".format(distance, degrees)
    if abs(bearing) <= BOX_AHEAD:
        return Check("laser_yaw", PASS, where + ": ahead, so the laser yaw ({:.2f} rad) is right".format(yaw))
    if simulated:
        return Check("laser_yaw", FAIL, where + ", not ahead: it is not a box in front of the robot",
                     SIM_BOX_HINT)
    better = _angle(yaw - round(bearing / (math.pi / 2)) * (math.pi / 2))
    return Check("laser_yaw", FAIL, where + ", not ahead: the laser yaw {:.2f} rad is wrong, or the box is not "
                 "the nearest thing".format(yaw),
                 "Nothing else within about 1.5 m (behind the robot included)? Then the yaw is wrong: set "
                 "ROBOT_LASER_YAW={:.5f} in /etc/flask-move-server/ros.env (a number, not pi) and restart "
                 "flask-move-server. Otherwise clear around the robot, or move it, and run the test again."
                 .format(better))


def _angle(value):
    """``value`` in (-pi, pi], so half a turn reads as +3.14159."""
    value = math.atan2(math.sin(value), math.cos(value))
    return math.pi if math.isclose(value, -math.pi) else value


# The share of laser end points on walls below which the pose is doubted: on the demo flat a right
# pose scores 1.0, one 0.3 m or 10 degrees off 0.38-0.76, one 0.1 m off 0.71-0.82 (test_scan_match.py).
SCAN_MATCH_WARN = 0.8


def scan_match_check(obs):
    """The laser against the map at the localized pose (navigation only): the evidence a covariance is not."""
    if obs.mode in ("idle", "mapping"):
        return Check("scan_match", SKIP, "the laser is matched against a saved map only while navigating")
    if obs.scan_match is None:
        return Check("scan_match", SKIP, "no map, pose or scan to match the laser against now")
    share, points = obs.scan_match
    summary = "{:.0f} % of the laser's {} points lie on the map's walls at the robot's pose".format(share * 100, points)
    if share < SCAN_MATCH_WARN:
        return Check("scan_match", WARN, summary + ": the laser does not match the map here",
                     "Set the robot's position: the page's Pose (drag until the laser's dots lie on the walls), "
                     "or robotctl pose X Y YAW. Furniture the map does not have lowers it too.")
    return Check("scan_match", PASS, summary)
