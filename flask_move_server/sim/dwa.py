"""dwa_local_planner's velocity sampling, as ROS Noetic's source does it: the rule the robot lives by.

The real local planner (``base_local_planner/src/simple_trajectory_generator.cpp``,
noetic-devel) samples velocities only within what the robot can reach in one
control period from its current ``/odom`` velocity, when ``use_dwa`` is true::

    max_vel = min(max_vel_x, vel + acc_lim × sim_period)
    min_vel = max(min_vel_x, vel − acc_lim × sim_period)     (θ: ±max_vel_theta)

``sim_period`` is ``1 / controller_frequency``, found by ``searchParam`` from
``~DWAPlannerROS`` upwards (``dwa_planner.cpp``): a DWA-local value wins over
move_base's. Each axis is sampled evenly, both ends included, with a 0 put in
where the range crosses it (``velocity_iterator.h``). ``generateTrajectory``
then drops a sample slower than *both* ``min_vel_trans`` and ``min_vel_theta``,
and one faster than ``max_vel_trans``. With no valid sample, move_base finds
no trajectory, runs its recoveries and aborts the goal.

Pure: the tests check the shipped configuration with it, and the simulated
move_base drives only with samples it allows, so a configuration that cannot
drive the robot does not drive the simulation either.
"""

import math
import os
from dataclasses import dataclass

import yaml

EPS = 1e-4  # generateTrajectory's tolerance on the minimum and maximum speeds


@dataclass(frozen=True)
class PlannerLimits:
    """The local planner's limits as DWAPlannerROS reads them (Noetic defaults where unset)."""

    max_vel_x: float = 0.55
    min_vel_x: float = 0.0
    max_vel_theta: float = 1.0
    min_vel_theta: float = 0.4
    max_vel_trans: float = 0.55
    min_vel_trans: float = 0.1
    acc_lim_x: float = 2.5
    acc_lim_theta: float = 3.2
    vx_samples: int = 3
    vth_samples: int = 20
    controller_frequency: float = 20.0  # the one DWA finds (its own, else move_base's)
    move_base_frequency: float = 20.0   # move_base's control loop
    controller_patience: float = 15.0
    xy_goal_tolerance: float = 0.1
    yaw_goal_tolerance: float = 0.05
    use_dwa: bool = True
    sim_time: float = 1.7

    @property
    def sim_period(self):
        """Seconds of one control period as DWA assumes it (0.05 s without a positive frequency)."""
        return 1.0 / self.controller_frequency if self.controller_frequency > 0 else 0.05

    @classmethod
    def from_params(cls, move_base, dwa):
        """From move_base's private params and its ``DWAPlannerROS`` namespace (two dicts)."""
        fields = {name: dwa[name] for name in cls.__dataclass_fields__ if name in dwa}
        fields.pop("move_base_frequency", None)
        fields.pop("controller_patience", None)
        own = move_base.get("controller_frequency", cls.controller_frequency)
        fields["controller_frequency"] = dwa.get("controller_frequency", own)
        fields["move_base_frequency"] = own
        fields["controller_patience"] = move_base.get("controller_patience", cls.controller_patience)
        return cls(**{k: (type(getattr(cls, k))(v)) for k, v in fields.items()})


def load(folder):
    """The limits in ``folder``'s move_base.yaml and dwa_local_planner.yaml (the robot's own files)."""
    move_base = _read(os.path.join(folder, "move_base.yaml"))
    dwa = _read(os.path.join(folder, "dwa_local_planner.yaml")).get("DWAPlannerROS", {})
    return PlannerLimits.from_params(move_base, dwa or {})


def _read(path):
    with open(path, encoding="utf-8") as f:
        return yaml.safe_load(f) or {}


def window(limits, linear, angular):
    """((min_x, max_x), (min_θ, max_θ)) DWA samples from the current velocity (linear, angular)."""
    period = limits.sim_period if limits.use_dwa else limits.sim_time
    reach_x, reach_th = limits.acc_lim_x * period, limits.acc_lim_theta * period
    x = (max(limits.min_vel_x, linear - reach_x), min(limits.max_vel_x, linear + reach_x))
    th = (max(-limits.max_vel_theta, angular - reach_th), min(limits.max_vel_theta, angular + reach_th))
    return x, th


def axis_samples(low, high, count):
    """velocity_iterator.h: ``count`` even steps from low to high, both included, 0 put in when crossed."""
    if low == high:
        return [low]
    count = max(2, count)
    step = (high - low) / (count - 1)
    samples, following = [], low
    for _ in range(count - 1):
        current, following = following, following + step
        samples.append(current)
        if current < 0 < following:
            samples.append(0.0)
    samples.append(high)
    return samples


def allowed(limits, linear, angular):
    """generateTrajectory's speed checks: moving fast enough on one axis, not too fast overall."""
    speed = abs(linear)
    too_slow = (limits.min_vel_trans >= 0 and speed + EPS < limits.min_vel_trans
                and limits.min_vel_theta >= 0 and abs(angular) + EPS < limits.min_vel_theta)
    too_fast = limits.max_vel_trans >= 0 and speed - EPS > limits.max_vel_trans
    return not (too_slow or too_fast)


def samples(limits, linear=0.0, angular=0.0):
    """The (linear, angular) velocities DWA may choose from the current velocity: the valid samples."""
    (x_low, x_high), (th_low, th_high) = window(limits, linear, angular)
    if x_low > x_high or th_low > th_high:
        return []
    return [(x, th) for x in axis_samples(x_low, x_high, limits.vx_samples)
            for th in axis_samples(th_low, th_high, limits.vth_samples) if allowed(limits, x, th)]


def turns_in_place(limits):
    """The valid samples from standstill that turn without driving: how the robot starts a goal behind it."""
    return [(x, th) for x, th in samples(limits) if x == 0.0 and th != 0.0]


def why_stuck_at_rest(limits):
    """None when DWA has samples from standstill (including a turn in place); else why not, in words."""
    if turns_in_place(limits):
        return None
    period = limits.sim_period
    return ("the local planner cannot start from standstill: in one control period (1/controller_frequency = "
            "{:.3g} s) it may reach {:.2g} m/s and {:.2g} rad/s (acc_lim_x {:g}, acc_lim_theta {:g}), below "
            "min_vel_trans {:g} and min_vel_theta {:g}, so dwa_local_planner finds no valid trajectory "
            "(config/dwa_local_planner.yaml, config/move_base.yaml)").format(
                period, limits.acc_lim_x * period, limits.acc_lim_theta * period, limits.acc_lim_x,
                limits.acc_lim_theta, limits.min_vel_trans, limits.min_vel_theta)


def nearest(limits, wanted, current):
    """The valid sample closest to the ``wanted`` (linear, angular) from ``current``; None if there is none.

    Distances weigh a radian per second like 0.2 m/s (the robot's turn radius scale), so a wanted
    turn is not traded for a drive.
    """
    options = samples(limits, *current)
    if not options:
        return None
    return min(options, key=lambda s: math.hypot((s[0] - wanted[0]) / 0.2, s[1] - wanted[1]))
