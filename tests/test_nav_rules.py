"""The real navigation nodes' rules, applied to the configuration the robot ships with.

move_base, dwa_local_planner, clear_costmap_recovery, rotate_recovery, AMCL and gmapping
cannot run here (Debian does not package them). Each test below recomputes what one of them
does with our files, from its Noetic source (file named in each test), so a configuration the
real robot cannot drive with fails ``make test``. Every rule also runs against the files as
shipped before issue 19 (tests/data/unfit_nav_config/), which it must reject.
"""

import math
import os
import re
import subprocess

import pytest
import yaml

from flask_move_server import config as config_mod
from flask_move_server.sim import dwa
from tests.conftest import ROOT
from tests.test_launch import launch_path, ros_env

SHIPPED = os.path.join(ROOT, "config")
UNFIT = os.path.join(ROOT, "tests", "data", "unfit_nav_config")
# move_base's defaults when recovery_behaviors is not set (move_base.cpp loadDefaultRecoveryBehaviors)
DEFAULT_RECOVERIES = [{"name": "conservative_reset", "type": "clear_costmap_recovery/ClearCostmapRecovery"},
                      {"name": "rotate_recovery", "type": "rotate_recovery/RotateRecovery"},
                      {"name": "aggressive_reset", "type": "clear_costmap_recovery/ClearCostmapRecovery"}]
CLEAR = "clear_costmap_recovery/ClearCostmapRecovery"
# An open-loop skid-steer misjudges its turns by 30-50 % (docs/wiring.md's calibration spin).
SKID_TURN_ERROR = 0.3


def read(folder, name):
    with open(os.path.join(folder, name + ".yaml"), encoding="utf-8") as f:
        return yaml.safe_load(f) or {}


def drive_config():
    return config_mod.load(os.path.join(ROOT, "config", "robot.yaml")).drive


# --- dwa_local_planner: the velocity window from standstill -------------------------------------

def test_dwa_starts_a_goal_from_standstill_with_a_turn_in_place_and_a_drive_off():
    limits = dwa.load(SHIPPED)
    assert dwa.why_stuck_at_rest(limits) is None
    assert dwa.turns_in_place(limits), "no valid turn in place from rest: a goal behind the robot never starts"
    assert any(x >= limits.min_vel_trans for x, _ in dwa.samples(limits)), "the robot cannot drive off from rest"


def test_dwa_as_shipped_before_finds_no_velocity_from_standstill():
    limits = dwa.load(UNFIT)
    assert dwa.samples(limits) == []
    reason = dwa.why_stuck_at_rest(limits)
    assert "0.08 m/s" in reason and "0.25 rad/s" in reason and "min_vel_theta 0.9" in reason


def test_the_window_is_the_generators_arithmetic():
    """simple_trajectory_generator.cpp with use_dwa, and velocity_iterator.h's samples, by hand."""
    limits = dwa.PlannerLimits(max_vel_x=0.3, min_vel_x=-0.1, max_vel_theta=1.2, min_vel_theta=0.9,
                               min_vel_trans=0.1, acc_lim_x=0.8, acc_lim_theta=4.0, vx_samples=4,
                               vth_samples=3, controller_frequency=4.0)
    assert dwa.window(limits, 0.0, 0.0) == (pytest.approx((-0.1, 0.2)), pytest.approx((-1.0, 1.0)))
    assert dwa.window(limits, 0.3, 1.0) == (pytest.approx((0.1, 0.3)), pytest.approx((0.0, 1.2)))
    assert dwa.axis_samples(-0.1, 0.2, 4) == pytest.approx([-0.1, 0.0, 0.0, 0.1, 0.2])
    assert dwa.axis_samples(-1.0, 1.0, 3) == [-1.0, 0.0, 1.0]
    assert not dwa.allowed(limits, 0.05, 0.5)       # slower than both minimums
    assert dwa.allowed(limits, 0.0, 0.9)            # a turn in place at min_vel_theta
    assert dwa.allowed(limits, 0.1, 0.0)            # straight at min_vel_trans


def test_a_dwa_local_controller_frequency_wins_over_move_base_s():
    """dwa_planner.cpp: searchParam("controller_frequency") from ~DWAPlannerROS upwards."""
    limits = dwa.PlannerLimits.from_params({"controller_frequency": 10.0}, {"controller_frequency": 4.0})
    assert limits.sim_period == 0.25 and limits.move_base_frequency == 10.0
    assert dwa.PlannerLimits.from_params({"controller_frequency": 10.0}, {}).sim_period == pytest.approx(0.1)


def test_dwa_asks_no_acceleration_the_drive_does_not_give():
    limits, drive = dwa.load(SHIPPED), drive_config()
    assert limits.acc_lim_x <= drive.max_linear_accel
    assert limits.acc_lim_theta <= drive.max_angular_accel


# --- move_base's recoveries -------------------------------------------------------------------

def costmap_layers(folder):
    """The layer names each costmap has (global_costmap.yaml, local_costmap.yaml plugins)."""
    layers = {}
    for name in ("global_costmap", "local_costmap"):
        layers[name] = {p["name"] for p in read(folder, name)[name]["plugins"]}
    return layers


def recoveries(folder):
    """(name, type, params) of each recovery move_base runs, with move_base's own defaults filled in."""
    move_base = read(folder, "move_base")
    entries = move_base.get("recovery_behaviors", DEFAULT_RECOVERIES)
    defaults = {"conservative_reset": {"reset_distance": move_base.get("conservative_reset_dist", 3.0)},
                "aggressive_reset": {"reset_distance": 0.46 * 4}} if "recovery_behaviors" not in move_base else {}
    return [(e["name"], e["type"], dict(defaults.get(e["name"], {}), **move_base.get(e["name"], {})))
            for e in entries]


def recovery_problems(folder):
    """clear_costmap_recovery.cpp: layer_names (default ["obstacles"]) matched against each layer's name."""
    problems = []
    layers = costmap_layers(folder)
    clears = [(name, params) for name, kind, params in recoveries(folder) if kind == CLEAR]
    for name, params in clears:
        for layer in params.get("layer_names", ["obstacles"]):
            if not all(layer in names for names in layers.values()):
                problems.append("{} clears layer {!r}, which the costmaps {} do not all have".format(
                    name, layer, layers))
    distances = {name: params.get("reset_distance", 3.0) for name, params in clears}
    # It clears everything OUTSIDE a square of side reset_distance: a smaller square clears more.
    if distances.get("aggressive_reset", 0) >= distances.get("conservative_reset", math.inf):
        problems.append("aggressive_reset keeps a {:.2f} m square, conservative_reset {:.2f} m: the aggressive "
                        "one clears less".format(distances["aggressive_reset"], distances["conservative_reset"]))
    return problems


def test_every_clear_costmap_recovery_clears_a_layer_the_costmaps_have():
    assert recovery_problems(SHIPPED) == []


def test_the_recoveries_shipped_before_cleared_nothing_and_aggressive_less():
    problems = recovery_problems(UNFIT)
    assert sum("'obstacles'" in p for p in problems) == 2
    assert any("clears less" in p for p in problems)


def rotate_recovery_speeds(folder):
    """rotate_recovery.cpp reads ~TrajectoryPlannerROS/: (min_in_place_vel_theta, max_vel_theta)."""
    limits = read(folder, "move_base").get("TrajectoryPlannerROS", {})
    return limits.get("min_in_place_vel_theta", 0.4), limits.get("max_vel_theta", 1.0)


@pytest.mark.parametrize("folder,fit", [(SHIPPED, True), (UNFIT, False)], ids=["shipped", "before"])
def test_rotate_recovery_turns_as_fast_as_the_drive_can_turn_in_place(folder, fit):
    low, high = rotate_recovery_speeds(folder)
    planner = dwa.load(folder)
    assert (low >= planner.min_vel_theta and high <= drive_config().max_angular) is fit


# --- AMCL's odometry model --------------------------------------------------------------------

def amcl_turn_noise(amcl):
    """Rotation noise (std dev) over a turn of update_min_a as a fraction of it (amcl_odom.cpp)."""
    step = amcl.get("update_min_a", math.pi / 6)
    alpha1 = amcl.get("odom_alpha1", 0.2)
    model = amcl.get("odom_model_type", "diff")
    spread = alpha1 * step * step  # "diff": this goes to pf_ran_gaussian as a standard deviation
    if model.endswith("-corrected"):
        spread = math.sqrt(spread)  # "diff-corrected": as a variance
    return spread / step


@pytest.mark.parametrize("folder,fit", [(SHIPPED, True), (UNFIT, False)], ids=["shipped", "before"])
def test_amcl_spreads_its_particles_as_wide_as_a_skid_steer_misjudges_a_turn(folder, fit):
    noise = amcl_turn_noise(read(folder, "amcl"))
    assert (SKID_TURN_ERROR <= noise <= 1.0) is fit, "rotation noise per turn: {:.0%}".format(noise)


def test_amcl_starts_from_its_own_covariance_not_the_last_run_s():
    """amcl writes initial_cov_* back to the master; a restarted stack must set them itself."""
    amcl = read(SHIPPED, "amcl")
    assert {"initial_cov_xx", "initial_cov_yy", "initial_cov_aa"} <= set(amcl)


# --- gmapping on a Pi 4 -----------------------------------------------------------------------

A1_MAX_BEAMS = 1160  # rplidar_ros with angle_compensate, the A1's densest scan mode


@pytest.mark.parametrize("folder,fit", [(SHIPPED, True), (UNFIT, False)], ids=["shipped", "before"])
def test_gmapping_fits_a_pi_4(folder, fit):
    gmapping = read(folder, "gmapping")
    scored = A1_MAX_BEAMS / (gmapping.get("lskip", 0) + 1)
    works_at_rest = gmapping.get("temporalUpdate", -1.0) >= 0
    rebuilds_often = gmapping.get("map_update_interval", 5.0) < 5.0
    assert (scored <= 400 and not works_at_rest and not rebuilds_often) is fit


def test_gmapping_does_not_take_its_range_from_the_scan():
    """slam_gmapping.cpp: maxRange defaults to scan.range_max - 0.01; rplidar_ros may publish 0."""
    gmapping = read(SHIPPED, "gmapping")
    assert gmapping["maxRange"] > 0 and 0 < gmapping["maxUrange"] <= gmapping["maxRange"]


# --- the laser's mounting ---------------------------------------------------------------------

def static_laser_yaw(env_extra=None, args=()):
    """The yaw navigation.launch hands tf2's static_transform_publisher for base_link -> laser."""
    env = ros_env()
    env.pop("ROBOT_LASER_YAW", None)
    env.update(env_extra or {})
    out = subprocess.run(["roslaunch", "--args", "base_link_to_laser", launch_path("navigation.launch"), *args],
                         env=env, capture_output=True, text=True, timeout=60)
    return out


def test_the_laser_yaw_default_is_a_number_and_matches_the_documented_mounting():
    out = static_laser_yaw()
    assert out.returncode == 0, out.stderr
    words = out.stdout.split()
    start = next(i for i, w in enumerate(words) if w.endswith("static_transform_publisher")) + 1
    yaw = words[start + 3]
    assert float(yaw) == pytest.approx(math.pi, abs=1e-6)
    with open(os.path.join(ROOT, "docs", "deploy.md"), encoding="utf-8") as f:
        deploy = f.read()
    # rplidar_ros's +x points at the motor (node.cpp: angle = pi - device angle): motor at the back is yaw pi.
    assert re.search(r"motor and its cable pointing backwards", deploy)
    assert "3.14159" in deploy


@pytest.mark.parametrize("value", ["pi", "180deg"])
def test_a_laser_yaw_tf2_would_read_as_zero_stops_roslaunch(value):
    out = static_laser_yaw({"ROBOT_LASER_YAW": value})
    assert out.returncode != 0
    assert value in out.stderr or "float" in out.stderr


def test_the_costmap_takes_the_scan_s_own_frame():
    """A fixed sensor_frame must be the lidar's frame; none at all follows the scan's frame_id."""
    scan = read(SHIPPED, "costmap_common")["obstacle_layer"]["scan"]
    assert "sensor_frame" not in scan
