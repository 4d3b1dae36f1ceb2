"""Putting the localization back where the laser fits the map, after it slid with the odometry. Pure.

While the wheels turned against the jamb, AMCL moved its estimate by the odometry the laser did
not see (the watch keeps it: ``MotionWatch.slip``). On the real stack the estimate went 0.36 m on,
through the wall, and three ``request_nomotion_update`` calls did not bring it back: the next goal
"arrived" a metre from where the robot stood. The slip is known, so the estimate is tried back
along it, in small steps up to :data:`BEYOND` times it, and the pose where the laser's end points
lie best on the map's walls (``diagnostics/scan_match.py``) is the one localization is told, when
it fits clearly better than the estimate does now.
"""

import math

from flask_move_server.core.geometry import compose, interpolate, inverse
from flask_move_server.diagnostics.scan_match import points_share

STEP = 0.02  # m between two poses tried along the slip
BEYOND = 1.5  # the poses tried reach this many times the slip back (the estimate may have slid further)
MIN_SLIP = 0.05  # m (or 0.05 rad) of slip: less is left to AMCL
BETTER = 0.1  # the share of end points on walls a pose must add to be told


def slipped(slip):
    """True when ``slip`` (Pose2D) is worth putting back."""
    return math.hypot(slip.x, slip.y) >= MIN_SLIP or abs(slip.yaw) >= MIN_SLIP


def put_back(grid, estimate, slip, points):
    """``(pose, share now, share there)``: where along ``slip`` back from ``estimate`` (Pose2D, map frame) the
    laser's ``points`` (robot frame) fit the map best, or None when no pose fits clearly better."""
    now, _ = points_share(grid, estimate, points)
    if now is None:
        return None
    back = compose(estimate, inverse(slip))  # where the robot is, if the estimate took the whole slip
    reach = BEYOND * max(math.hypot(slip.x, slip.y), abs(slip.yaw) * 0.2)
    steps = max(1, int(math.ceil(reach / STEP)))
    tried = [(now, estimate)]
    for k in range(1, steps + 1):
        pose = interpolate(estimate, back, BEYOND * k / steps)
        share, _ = points_share(grid, pose, points)
        tried.append((share if share is not None else 0.0, pose))
    best = max(share for share, _ in tried)
    if best < now + BETTER:
        return None
    # A wall counts an end point within a cell of it, so several poses a few cm apart fit as well: the
    # middle of them is nearest to where the robot is.
    fitting = [pose for share, pose in tried if share >= best - 1e-9]
    return fitting[len(fitting) // 2], now, best
