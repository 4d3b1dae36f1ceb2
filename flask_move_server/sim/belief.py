"""What the simulated localization believes, beside the truth: AMCL's answer to a pose estimate.

AMCL (``handleInitialPoseMessage``) re-initialises its particle filter around an estimate (with the
estimate's covariance) and moves it on by the odometry; with a laser it then converges to the truth
over motion when the truth lies inside that cloud of particles, and not when it is metres away (the
particles never cover it; the filter stays where it was told, or locks onto a look-alike spot).

:class:`Belief` keeps that as a correction of the truth (belief = correction ∘ true pose: the
estimate moved on by the robot's own motion). When the truth lies within ``SPREAD`` standard
deviations of the estimate, each filter update (``UPDATE_MIN_D`` of travel or ``UPDATE_MIN_A`` of
turn, the shipped config/amcl.yaml's) halves the error; otherwise the belief is kept until the next
estimate. A robot at rest never converges (AMCL does not update without motion). Pure: no rospy.
"""

import math
import threading

from flask_move_server.core.geometry import Pose2D, compose, interpolate, inverse, normalize_angle

IDENTITY = Pose2D(0.0, 0.0, 0.0)
SPREAD = 2.0  # standard deviations of the estimate within which the truth is inside the particle cloud
UPDATE_MIN_D = 0.1  # m of travel between AMCL's filter updates (config/amcl.yaml update_min_d)
UPDATE_MIN_A = 0.2  # rad of turn between them (update_min_a)
SETTLED = 1e-3  # m and rad: an error this small is none
SLIDE_CAP = 0.15  # m the belief slides from the truth at most while the wheels turn against a wall


class Belief:
    """The localization's belief as a correction of the true pose; thread-safe."""

    def __init__(self):
        self._lock = threading.Lock()
        self._correction = IDENTITY
        self._converging = False
        self._updated_at = None  # the true pose at the last filter update

    def of(self, true):
        """The pose localization believes the robot is at, when it really is at ``true``."""
        return compose(self._correction, true)

    def estimate(self, estimate, true, sigma_xy, sigma_yaw):
        """A pose estimate (with its standard deviations) arrives while the robot really is at ``true``."""
        error = compose(inverse(true), estimate)
        inside = (math.hypot(error.x, error.y) <= SPREAD * sigma_xy
                  and abs(normalize_angle(error.yaw)) <= SPREAD * sigma_yaw)
        with self._lock:
            self._correction = compose(estimate, inverse(true))
            self._converging = inside
            self._updated_at = true
        return inside

    def moved(self, true):
        """The robot is now really at ``true``: one filter update per step of motion, while converging."""
        with self._lock:
            if self._converging and _a_step(self._updated_at, true):
                self._update(true)

    def slid(self, before, odometry, true, cap=SLIDE_CAP):
        """The wheels turned by ``odometry`` (the motion the odometry counted) but the robot was blocked and
        is really at ``true``: AMCL's motion model moves the filter by the odometry, so the belief slides from
        ``before`` into what blocked it, at most ``cap`` metres from the truth; the laser pulls it back at the
        filter's next updates (issue 33: the real robot's localized pose slid into the door jamb)."""
        slid = compose(before, odometry)
        if math.hypot(slid.x - true.x, slid.y - true.y) > cap:
            return
        with self._lock:
            self._correction = compose(slid, inverse(true))
            self._converging = True
            self._updated_at = true

    def look_again(self, true):
        """One filter update without motion (AMCL's ``request_nomotion_update``), while converging."""
        with self._lock:
            if self._converging:
                self._update(true)

    def _update(self, true):
        """Lock held: one filter update at ``true``, halving the error."""
        self._updated_at = true
        error = compose(inverse(true), compose(self._correction, true))  # the belief in the robot's frame
        halved = interpolate(error, IDENTITY, 0.5)
        if math.hypot(halved.x, halved.y) < SETTLED and abs(halved.yaw) < SETTLED:
            self._correction, self._converging = IDENTITY, False
            return
        self._correction = compose(compose(true, halved), inverse(true))


def _a_step(before, after):
    return (math.hypot(after.x - before.x, after.y - before.y) >= UPDATE_MIN_D
            or abs(normalize_angle(after.yaw - before.yaw)) >= UPDATE_MIN_A)
