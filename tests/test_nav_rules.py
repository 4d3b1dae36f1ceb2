"""The real navigation nodes' rules, applied to the configuration the robot ships with.

move_base, dwa_local_planner, clear_costmap_recovery, rotate_recovery, AMCL and gmapping
cannot run here (Debian does not package them). Each test below recomputes what one of them
does with our files, from its Noetic source (file named in each test), so a configuration the
real robot cannot drive with fails ``make test``. Every rule also runs against the files as
shipped before issue 19 (tests/data/unfit_nav_config/), which it must reject; the rules for
move_base on a growing map (issue 24) run against what roslaunch gives move_base in each mode,
and against that with the one value each rule guards changed, which they must reject.
"""

import copy
import functools
import math
import os
import re
import shutil
import subprocess

import pytest
import yaml

from flask_move_server import config as config_mod
from flask_move_server.sim import dwa
from flask_move_server.zones import TOPIC, costmap_rules
from tests.conftest import ROOT
from tests.test_launch import dump_params, launch_path, ros_env

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


# --- move_base on a growing map (mapping) and on a saved one (navigation) ----------------------
# Sources: ros-planning/navigation noetic-devel (costmap_2d, navfn, move_base, base_local_planner),
# ros-perception/slam_gmapping melodic-devel (Noetic's release), cost values from
# costmap_2d/include/costmap_2d/cost_values.h.

NO_INFORMATION, LETHAL_OBSTACLE, INSCRIBED, FREE_SPACE = 255, 254, 253, 0
GMAPPING_UNKNOWN = -1  # slam_gmapping.cpp updateMap: a cell never seen is -1 (0 free, 100 occupied)
MODES = {"mapping": ("mapping.launch", ["server:=false", "lidar:=false"]),
         "navigation": ("navigation.launch", ["server:=false", "lidar:=false"])}


@functools.lru_cache(maxsize=None)
def _move_base_params(mode):
    launch, args = MODES[mode]
    tree = {}
    for key, value in dump_params(launch, args).items():
        if key.startswith("/move_base/"):
            *parents, leaf = key[len("/move_base/"):].split("/")
            branch = tree
            for part in parents:
                branch = branch.setdefault(part, {})
            branch[leaf] = value
    return tree


def move_base_params(mode, **changes):
    """move_base's private params as roslaunch sets them in ``mode``; ``changes``: "a/b/c" (as a__b__c) = value."""
    tree = copy.deepcopy(_move_base_params(mode))
    for path, value in changes.items():
        *parents, leaf = path.split("__")
        branch = tree
        for part in parents:
            branch = branch.setdefault(part, {})
        branch[leaf] = value
    return tree


def layer(costmap, kind):
    """The params of the first layer of type ``kind`` in ``costmap``'s plugins (None: no such layer)."""
    for plugin in costmap.get("plugins", []):
        if plugin["type"] == kind:
            return costmap.get(plugin["name"], {})
    return None


def static_layer_cost(static, value):
    """StaticLayer::interpretValue (static_layer.cpp 150-164): an OccupancyGrid value as a cost.

    The message's int8 and the int param are both kept as unsigned char (static_layer.h 94), so
    unknown_cost_value -1 matches gmapping's -1 (255 == 255); defaults from onInitialize (74-83).
    """
    value &= 0xFF
    unknown = static.get("unknown_cost_value", -1) & 0xFF
    lethal = max(min(static.get("lethal_cost_threshold", 100), 100), 0)
    if static.get("track_unknown_space", True) and value == unknown:
        return NO_INFORMATION
    if not static.get("track_unknown_space", True) and value == unknown:
        return FREE_SPACE
    if value >= lethal:
        return LETHAL_OBSTACLE
    if static.get("trinary_costmap", True):
        return FREE_SPACE
    return int(value / lethal * LETHAL_OBSTACLE)


def unseen_cell_cost(mb):
    """The global costmap's cost, as navfn reads it, of a cell gmapping has not seen, in the laser's reach.

    Static layer first (updateWithTrueOverwrite copies every cell, costmap_layer.cpp 89-106), then
    the obstacle layer, whose cells no scan marked or cleared hold its default: NO_INFORMATION with
    track_unknown_space, else FREE_SPACE (obstacle_layer.cpp 62-67; the default follows the
    costmap's own track_unknown_space, false by default: costmap_2d_ros.cpp 109). It writes its
    cells over the master within the scans' bounds by combination_method (default 1,
    ObstaclePlugin.cfg; obstacle_layer.cpp 436-446): max and overwrite skip NO_INFORMATION and
    otherwise replace an unknown master cell (costmap_layer.cpp 63-87, 108-125). The inflation
    layer leaves a cell far from obstacles as it is (inflation_layer.cpp 261-265).
    """
    costmap = mb["global_costmap"]
    static = layer(costmap, "costmap_2d::StaticLayer")
    cost = static_layer_cost(static, GMAPPING_UNKNOWN) if static is not None else (
        NO_INFORMATION if costmap.get("track_unknown_space", False) else FREE_SPACE)
    cost = later_static_layers(costmap, cost, rolling=False)
    obstacles = layer(costmap, "costmap_2d::ObstacleLayer")
    if obstacles is not None:
        default = NO_INFORMATION if obstacles.get("track_unknown_space", costmap.get("track_unknown_space", False)) \
            else FREE_SPACE
        method = obstacles.get("combination_method", 1)
        if default != NO_INFORMATION and (method == 0 or (method == 1 and (cost == NO_INFORMATION or cost < default))):
            cost = default
    return cost


def static_layers(costmap):
    """The params of each StaticLayer in ``costmap``'s plugins, in order."""
    return [costmap.get(p["name"], {}) for p in costmap.get("plugins", []) if p["type"] == "costmap_2d::StaticLayer"]


def later_static_layers(costmap, cost, rolling):
    """The cost of an unseen cell after the StaticLayers past the first (the zones' mask: -1 where no zone is,
    zones/mask.py) wrote it over ``cost``. Not rolling: use_maximum is updateWithMax, which skips the layer's
    NO_INFORMATION and otherwise replaces an unknown master cell (costmap_layer.cpp 63-87), else
    updateWithTrueOverwrite (89-106). Rolling: the larger of the two, or the layer's (static_layer.cpp 313-344)."""
    for static in static_layers(costmap)[0 if rolling else 1:]:
        mine = static_layer_cost(static, -1)
        if not static.get("use_maximum", False):
            cost = mine
        elif rolling:
            cost = max(cost, mine)
        elif mine != NO_INFORMATION and (cost == NO_INFORMATION or cost < mine):
            cost = mine
    return cost


def navfn_cell(mb, cost):
    """NavFn::setCostmap (navfn.cpp 228-256): a ROS cost as navfn's, or None where it never plans.

    Below INSCRIBED (253): COST_NEUTRAL 50 + 0.8 x cost, at most 253. NO_INFORMATION (255): 253,
    the dearest cell it still passes, with ~NavfnROS/allow_unknown (navfn_ros.cpp 79, default
    true; passed at 149 and 238); else, like 253 and 254, an obstacle (COST_OBS).
    """
    if cost < INSCRIBED:
        return min(50 + int(0.8 * cost), 253)
    if cost == NO_INFORMATION and mb.get("NavfnROS", {}).get("allow_unknown", True):
        return 253
    return None


def change_id(value):
    """A test id for a parameter: ``changes`` shown as the keys they set."""
    if isinstance(value, dict):
        return ",".join("{}={}".format(k.replace("__", "/"), v) for k, v in value.items())
    return str(value)


def plans_through_unseen_space(mb):
    """How navfn treats space gmapping has not seen: "never", "dearest" (passed when it must), or "as free"."""
    planned = navfn_cell(mb, unseen_cell_cost(mb))
    if planned is None:
        return "never"
    return "dearest" if planned > navfn_cell(mb, FREE_SPACE) else "as free"


def test_mapping_s_global_planner_plans_through_space_the_map_has_not_seen_yet():
    """A goal at the edge of the growing map, or past it, gets a path through unknown cells, at navfn's
    dearest passable cost, so known free space is still preferred: NavfnROS/allow_unknown AND the
    static layer's track_unknown_space (without it the unknown cell is FREE_SPACE and navfn crosses
    unseen space as gladly as seen free space) AND the obstacle layer's (else its FREE_SPACE default
    overwrites the unknown cells around the robot)."""
    assert plans_through_unseen_space(move_base_params("mapping")) == "dearest"


def test_navigation_never_plans_through_space_the_saved_map_has_not_seen():
    assert plans_through_unseen_space(move_base_params("navigation")) == "never"


@pytest.mark.parametrize("mode,change,planned", [
    ("mapping", {"NavfnROS__allow_unknown": False}, "never"),
    ("mapping", {"global_costmap__static_layer__track_unknown_space": False}, "as free"),
    ("mapping", {"global_costmap__obstacle_layer__track_unknown_space": False}, "as free"),
    ("mapping", {"global_costmap__static_layer__unknown_cost_value": 0}, "never"),  # -1 is then lethal
    ("navigation", {"NavfnROS__allow_unknown": True}, "dearest"),
    # allow_unknown false does not keep navfn out of unseen space the costmap turned into free space:
    ("navigation", {"global_costmap__static_layer__track_unknown_space": False}, "as free"),
    ("navigation", {"global_costmap__obstacle_layer__track_unknown_space": False}, "as free"),
    # the zones' mask read as free where no zone is would write free over the map's unseen cells:
    ("navigation", {"global_costmap__keepout_layer__track_unknown_space": False}, "as free"),
], ids=lambda v: change_id(v))
def test_each_key_the_unseen_space_rules_rest_on_decides_them(mode, change, planned):
    assert plans_through_unseen_space(move_base_params(mode, **change)) == planned


def follows_a_growing_map(mb):
    """What keeps the global costmap on gmapping's latest /map, or None.

    slam_gmapping publishes the whole map, latched, on ``map`` (and ``map_metadata``) after each
    update, its size and origin changed when it grew (slam_gmapping.cpp 272-273, 733-750, 780-781);
    it publishes no ``map_updates`` (nor does hector_mapping: HectorMappingRos.cpp 152-153), so
    subscribe_to_updates is not what follows it. The static layer stays subscribed to ``map_topic``
    unless first_map_only (static_layer.cpp 71, 219-224), and on a map of another size or origin
    resizes the whole costmap, every layer with it, unless the costmap is a rolling window
    (static_layer.cpp 172-186; layered_costmap.cpp 82-93).
    """
    costmap = mb["global_costmap"]
    static = layer(costmap, "costmap_2d::StaticLayer")
    if static is None or not static.get("enabled", True):
        return "the global costmap has no static layer (or it is disabled): the map never reaches it"
    if static.get("map_topic", "map") != "map":
        return "the static layer listens on {}, gmapping publishes map".format(static["map_topic"])
    if static.get("first_map_only", False):
        return "first_map_only: the static layer keeps gmapping's first map, a few metres around the start"
    if costmap.get("rolling_window", False):
        return "rolling_window: the costmap keeps its own size and never takes the map's"
    return None


def test_mapping_s_global_costmap_follows_the_map_as_it_grows():
    assert follows_a_growing_map(move_base_params("mapping")) is None


@pytest.mark.parametrize("change,why", [
    ({"global_costmap__static_layer__first_map_only": True}, "first_map_only"),
    ({"global_costmap__rolling_window": True}, "rolling_window"),
    ({"global_costmap__static_layer__map_topic": "map_server_map"}, "listens on map_server_map"),
    ({"global_costmap__static_layer__enabled": False}, "no static layer"),
], ids=lambda v: change_id(v))
def test_a_costmap_that_keeps_the_first_map_is_caught(change, why):
    assert why in (follows_a_growing_map(move_base_params("mapping", **change)) or "")


def replans_as_the_map_grows(mb):
    """move_base.cpp planThread (575-648): with planner_frequency <= 0 (its default, 74) the first plan
    found ends planning for the goal (611-612), and a wall gmapping adds across that plan is met only
    when the local planner fails; above 0 it replans every 1/planner_frequency s."""
    return mb.get("planner_frequency", 0.0) > 0


def test_mapping_replans_as_the_map_grows():
    assert replans_as_the_map_grows(move_base_params("mapping"))
    assert not replans_as_the_map_grows(move_base_params("mapping", planner_frequency=0.0))


def local_costmap_unseen_cost(mb):
    """The local costmap's cost for a cell no layer has information about.

    The costmap's own track_unknown_space (default false, costmap_2d_ros.cpp 109) sets the master's
    default, NO_INFORMATION or FREE_SPACE (layered_costmap.cpp 68-71); the obstacle layer's unknown
    cells are skipped (costmap_layer.cpp 76-79) and a static layer would write them (89-106).
    """
    costmap = mb["local_costmap"]
    default = NO_INFORMATION if costmap.get("track_unknown_space", False) else FREE_SPACE
    return later_static_layers(costmap, default, rolling=True)


@pytest.mark.parametrize("mode", sorted(MODES))
def test_dwa_drives_into_space_the_map_has_not_seen(mode):
    """base_local_planner's CostmapModel refuses a footprint on a NO_INFORMATION cell (costmap_model.cpp
    134-143, -2): a local costmap that kept unknown space would stop the robot at every frontier."""
    assert local_costmap_unseen_cost(move_base_params(mode)) == FREE_SPACE
    assert local_costmap_unseen_cost(move_base_params(mode, local_costmap__track_unknown_space=True)) == NO_INFORMATION
    if mode == "navigation":  # the zones' mask read as unknown where no zone is would win every cell's max
        changed = move_base_params(mode, local_costmap__keepout_layer__track_unknown_space=True)
        assert local_costmap_unseen_cost(changed) == NO_INFORMATION


# --- keeping the footprint off door jambs (issue 33): costmap_2d's inflation, navfn's path, DWA ---
# With the real Noetic move_base on the simulated flat, navfn's plans passed the demo's 0.9 m doors
# with 0.17 m between the footprint and a jamb at the closest (the bedroom door), and a robot that
# cut a jamb while exploring wedged there. The inflation below decides how far the plans keep off.

DEMO_MAP = os.path.join(ROOT, "config", "maps", "demo.yaml")
DOOR_ROUTES = [((0.0, 1.6), (-0.8, 4.3)), ((0.0, 0.0), (6.2, 4.5)), ((0.0, 0.0), (8.4, 0.9))]  # office, bedroom,
# kitchen: through each of the flat's three doors
JAMB_CLEARANCE = 0.25  # m between the (unpadded) footprint and a wall, at the closest, on a plan through a door
OPEN_LOOP_ERROR = 0.1  # m the L298N drive's open-loop odometry is off over a room (docs/wiring.md's calibration)


def inflation_params(folder):
    """(inscribed radius, inflation_radius, cost_scaling_factor, resolution) as move_base's costmaps take them:
    the padded footprint's inscribed radius (costmap_2d footprint.cpp calculateMinAndMaxDistances)."""
    from flask_move_server.recovery import footprint

    common = read(folder, "costmap_common")
    inflation = common.get("inflation_layer", {})
    return (footprint.inscribed_radius(footprint.read(folder)), inflation.get("inflation_radius", 0.55),
            inflation.get("cost_scaling_factor", 10.0), read(folder, "global_costmap")["global_costmap"]["resolution"])


def inflated_cost(distance, inscribed, radius, scaling):
    """InflationLayer::computeCost (inflation_layer.h 130-143) of a cell ``distance`` m from the nearest lethal
    one: LETHAL on it, INSCRIBED within the inscribed radius, 252 exp(-k (d - r_in)) out to the inflation
    radius (cells farther than it are not inflated: FREE_SPACE)."""
    if distance == 0:
        return LETHAL_OBSTACLE
    if distance <= inscribed:
        return INSCRIBED
    if distance > radius:
        return FREE_SPACE
    return int((INSCRIBED - 1) * math.exp(-scaling * (distance - inscribed)))


def navfn_costs(folder):
    """The demo map as navfn plans on it in navigation: the static layer's lethal cells inflated by the
    folder's inflation (distances between cell centres, as the layer's cached_distances_), each cell then
    as NavFn::setCostmap reads it (navfn_cell; unknown is an obstacle, allow_unknown false); and the
    lethal cells' centres, for clearances."""
    import numpy as np

    from flask_move_server.sim import occupancy

    grid = occupancy.load(DEMO_MAP)
    cells = np.asarray(grid.cells, dtype=np.int16).reshape(grid.height, grid.width)
    lethal, unknown = cells >= 65, cells < 0
    inscribed, radius, scaling, resolution = inflation_params(folder)
    reach = int(math.ceil(radius / resolution))
    distance = np.full(cells.shape, np.inf)
    for dr in range(-reach, reach + 1):
        for dc in range(-reach, reach + 1):
            d = math.hypot(dr, dc) * resolution
            if d <= radius + 1e-9:
                shifted = np.zeros_like(lethal)
                shifted[max(0, dr):cells.shape[0] + min(0, dr), max(0, dc):cells.shape[1] + min(0, dc)] = \
                    lethal[max(0, -dr):cells.shape[0] - max(0, dr), max(0, -dc):cells.shape[1] - max(0, dc)]
                distance[shifted] = np.minimum(distance[shifted], d)
    mb = {"NavfnROS": {"allow_unknown": False}}
    costs = {}
    for row, col in zip(*np.nonzero(~unknown)):
        planned = navfn_cell(mb, inflated_cost(distance[row, col], inscribed, radius, scaling))
        if planned is not None:
            costs[(int(col), int(row))] = planned
    walls = [grid.center_of(int(c), int(r)) for r, c in zip(*np.nonzero(lethal))]
    return grid, costs, walls


def navfn_plan(grid, costs, start, goal):
    """The cheapest path over navfn's cell costs from ``start`` to ``goal`` (map frame), as cell centres: navfn's
    potential is this sum of costs along the way (its wavefront, navfn.cpp updateCell; 8 neighbours here)."""
    import heapq

    begin, end = grid.cell_of(*start), grid.cell_of(*goal)
    best, came, queue = {begin: 0.0}, {}, [(0.0, begin)]
    while queue:
        cost, cell = heapq.heappop(queue)
        if cell == end:
            break
        if cost > best[cell]:
            continue
        for dc, dr, step in ((1, 0, 1.0), (-1, 0, 1.0), (0, 1, 1.0), (0, -1, 1.0), (1, 1, 1.414), (1, -1, 1.414),
                             (-1, 1, 1.414), (-1, -1, 1.414)):
            near = (cell[0] + dc, cell[1] + dr)
            if near in costs and cost + step * costs[near] < best.get(near, math.inf):
                best[near], came[near] = cost + step * costs[near], cell
                heapq.heappush(queue, (best[near], near))
    path = [end]
    while path[-1] != begin:
        path.append(came[path[-1]])
    return [grid.center_of(*cell) for cell in reversed(path)]


def footprint_clearance(points, walls, polygon, along=4):
    """The least distance from the footprint, heading along the path (over ``along`` cells), to a wall cell's edge."""
    import numpy as np

    walls = np.asarray(walls)
    half_x, half_y = max(abs(x) for x, _ in polygon), max(abs(y) for _, y in polygon)
    least = math.inf
    for i, (x, y) in enumerate(points):
        a, b = points[max(0, i - along)], points[min(len(points) - 1, i + along)]
        yaw = math.atan2(b[1] - a[1], b[0] - a[0])
        near = walls[np.hypot(walls[:, 0] - x, walls[:, 1] - y) < 0.6]
        if len(near):
            c, s = math.cos(yaw), math.sin(yaw)
            dx, dy = near[:, 0] - x, near[:, 1] - y
            lx, ly = np.abs(c * dx + s * dy) - half_x, np.abs(-s * dx + c * dy) - half_y
            least = min(least, float(np.min(np.hypot(np.maximum(lx, 0), np.maximum(ly, 0)))) - 0.025)
    return least


def door_clearance(folder):
    """The least footprint clearance of navfn's plans through the demo flat's doors with ``folder``'s costmaps."""
    from flask_move_server.recovery import footprint

    grid, costs, walls = navfn_costs(folder)
    body = footprint.read_polygon(folder)
    return min(footprint_clearance(navfn_plan(grid, costs, a, b), walls, body) for a, b in DOOR_ROUTES)


def test_navfn_keeps_the_footprint_a_quarter_metre_off_the_door_jambs():
    """Inflated past half a door's width, every cell of a doorway costs more than the free floor, the more the
    nearer a jamb: navfn's cheapest way through runs down its middle. The real navfn with these values kept
    0.28-0.29 m on these routes (0.17 m with the values shipped before): more than the open-loop odometry's
    error over a room, so the robot's true footprint stays off the jambs too."""
    _, radius, _, _ = inflation_params(SHIPPED)
    assert radius > 0.9 / 2, "the inflation must reach the middle of a 0.9 m door, or the path may hug a jamb"
    assert door_clearance(SHIPPED) >= JAMB_CLEARANCE > 2 * OPEN_LOOP_ERROR


def test_the_inflation_shipped_before_let_navfn_cut_the_jambs(tmp_path):
    folder = tmp_path / "before"
    shutil.copytree(SHIPPED, str(folder))
    common = read(str(folder), "costmap_common")
    common["inflation_layer"].update(inflation_radius=0.35, cost_scaling_factor=5.0)
    (folder / "costmap_common.yaml").write_text(yaml.safe_dump(common))
    assert door_clearance(str(folder)) < JAMB_CLEARANCE


def dwa_off_the_plan(folder):
    """(cost of a trajectory one cell farther off the plan, gain of its footprint edge one cell out of the
    inscribed band), as dwa_planner.cpp scores them: path and alignment costs in cells scaled by resolution x
    path_distance_bias (the alignment at half that while the goal is farther than forward_point_distance:
    updatePlanAndLocalCosts), the obstacle cost by occdist_scale x the footprint outline's highest cell cost
    (obstacle_cost_function.cpp, costmap_model.cpp footprintCost/lineCost)."""
    dwa_params = read(folder, "dwa_local_planner")["DWAPlannerROS"]
    inscribed, radius, scaling, resolution = inflation_params(folder)
    off_the_plan = resolution * dwa_params["path_distance_bias"] * (1.0 + 0.5)
    out_of_the_band = dwa_params["occdist_scale"] * (
        inflated_cost(inscribed, inscribed, radius, scaling)
        - inflated_cost(inscribed + resolution, inscribed, radius, scaling))
    return off_the_plan, out_of_the_band


def test_dwa_steps_off_the_plan_rather_than_scrape_what_it_passes():
    """A plan that cuts a corner (one seen late, a chair the map lacks) is followed by DWA until the footprint
    touches it unless leaving the plan by a cell to take the footprint off the inscribed band scores better."""
    cost, gain = dwa_off_the_plan(SHIPPED)
    assert gain > cost, "occdist_scale x {:.0f} < {:.1f}".format(gain, cost)


def test_the_dwa_weights_shipped_before_followed_the_plan_onto_the_wall(tmp_path):
    folder = tmp_path / "before"
    shutil.copytree(SHIPPED, str(folder))
    params = read(str(folder), "dwa_local_planner")
    params["DWAPlannerROS"]["occdist_scale"] = 0.02
    (folder / "dwa_local_planner.yaml").write_text(yaml.safe_dump(params))
    cost, gain = dwa_off_the_plan(str(folder))
    assert gain < cost


# --- map -> odom dated ahead of a Pi's stall, in both modes (issue 33) --------------------------
# With the real stack, mapping logged 107 "Extrapolation Error ... into the future" in 7 min and a first
# goal aborted on "Received an empty transformed plan" (navigation: none). DWA turns the global plan into
# the odom frame at the plan's stamp (base_local_planner goal_functions.cpp transformGlobalPlan), which
# navfn stamps with the time it planned; tf cannot give map -> odom past its newest stamp. AMCL dates
# map -> odom transform_tolerance ahead of the scan it comes from (amcl_node.cpp 1486), gmapping tf_delay
# ahead of the time it publishes (slam_gmapping.cpp 803), every transform_publish_period (360).

PI_STALL = 0.1  # s a busy Pi 4 holds a node's thread (gmapping's scan matching, a Python GC)


def map_to_odom_lead(mode):
    """(how far ahead map -> odom is dated, how often it is published) as roslaunch sets the SLAM / AMCL node."""
    params = dump_params(*MODES[mode])
    if mode == "mapping":
        period = params.get("/slam_gmapping/transform_publish_period", 0.05)
        return params.get("/slam_gmapping/tf_delay", period), period  # tf_delay defaults to the period
    return params.get("/amcl/transform_tolerance", 0.1), None  # with each scan (the A1: ~0.18 s apart)


def leads_a_stall(lead, period):
    """A plan stamped now finds map -> odom at that time while the node publishing it is held up: dated at
    least a stall (and, for gmapping, a period) ahead."""
    return lead >= PI_STALL + (period or 0.0)


@pytest.mark.parametrize("mode", ["mapping", "navigation"])
def test_map_to_odom_is_dated_ahead_of_a_pi_s_stall(mode):
    lead, period = map_to_odom_lead(mode)
    assert leads_a_stall(lead, period), (mode, lead, period)


def test_the_costmaps_wait_as_long_as_map_to_odom_is_dated_ahead():
    """costmap_2d_ros.cpp getRobotPose: a robot pose older than transform_tolerance is a transform timeout
    (16 while mapping, with the real stack): the tolerance covers the stall, and gmapping's lead as AMCL's."""
    tolerance = read(SHIPPED, "costmap_common")["transform_tolerance"]
    assert tolerance >= PI_STALL + 1.0 / drive_config().odom_rate
    assert map_to_odom_lead("mapping")[0] <= tolerance and map_to_odom_lead("navigation")[0] <= tolerance


def test_gmapping_as_shipped_before_dated_map_to_odom_only_a_period_ahead():
    period = read(SHIPPED, "gmapping")["transform_publish_period"]
    assert not leads_a_stall(period, period)  # no tf_delay: slam_gmapping.cpp takes the period


# --- costmap_2d's StaticLayer on keepout_map: the owner's zones (issue 36) ---------------------------

def keepout_problems_in(mb):
    """Why move_base's costmaps, as roslaunch gives them in navigation, would not keep out of the zones."""
    return ["{}: {}".format(name, p) for name in ("global_costmap", "local_costmap")
            for p in costmap_rules.keepout_problems(mb[name], TOPIC)]


def test_both_costmaps_read_the_zones_mask_as_the_server_publishes_it():
    """A second StaticLayer on keepout_map in each costmap (static_layer.cpp 62-124), adding to the map
    (use_maximum: costmap_layer.cpp 63-87), taking every new mask (first_map_only false, 219-224), the
    mask's -1 read as unknown in the global costmap and as free in the rolling local one (150-164, 313-344),
    100 as lethal, before inflation (inflation_layer.cpp 219-231)."""
    assert keepout_problems_in(move_base_params("navigation")) == []


def test_mapping_s_costmaps_wait_for_no_mask():
    """The server publishes no mask under gmapping's growing map, and a StaticLayer waits for its first
    message at start-up (static_layer.cpp 94-99): a keepout layer while mapping would hang move_base."""
    mb = move_base_params("mapping")
    assert [costmap_rules.keepout_layer(mb[name], TOPIC) for name in ("global_costmap", "local_costmap")] == \
        [None, None]


SHIPPED_GLOBAL_LAYERS = [{"name": "static_layer", "type": "costmap_2d::StaticLayer"},
                         {"name": "obstacle_layer", "type": "costmap_2d::ObstacleLayer"},
                         {"name": "inflation_layer", "type": "costmap_2d::InflationLayer"},
                         {"name": "keepout_layer", "type": "costmap_2d::StaticLayer"}]


@pytest.mark.parametrize("change,why", [
    ({"global_costmap__keepout_layer__use_maximum": False}, "global_costmap: use_maximum is false"),
    ({"local_costmap__keepout_layer__first_map_only": True}, "local_costmap: first_map_only is true"),
    ({"global_costmap__keepout_layer__track_unknown_space": False}, "global_costmap: the mask's cells outside"),
    ({"local_costmap__keepout_layer__track_unknown_space": True}, "local_costmap: the mask's cells outside"),
    ({"global_costmap__keepout_layer__unknown_cost_value": 100}, "not read as lethal"),
    ({"global_costmap__keepout_layer__map_topic": "keepout"}, "global_costmap: no costmap_2d::StaticLayer reads"),
    ({"global_costmap__map_topic": "map"}, "global_costmap: no costmap_2d::StaticLayer reads"),
    ({"global_costmap__keepout_layer__enabled": False}, "disabled"),
    ({"global_costmap__plugins": SHIPPED_GLOBAL_LAYERS}, "after the inflation layer"),
], ids=lambda v: ("layer order" if "global_costmap__plugins" in v else change_id(v)) if isinstance(v, dict) else "")
def test_a_costmap_that_would_let_the_robot_into_a_zone_is_caught(change, why):
    assert any(why in p for p in keepout_problems_in(move_base_params("navigation", **change))), why


def test_the_simulation_obeys_the_zones_only_where_the_real_costmaps_would(tmp_path):
    """The sim reads the same files the same way (zones/costmap_rules.py move_base_costmaps, as
    move_base.launch loads them): a copy with the keepout layer after inflation does not obey."""
    assert costmap_rules.obeys_zones(SHIPPED, TOPIC) == (True, [])
    folder = tmp_path / "config"
    shutil.copytree(SHIPPED, str(folder))
    text = (folder / "costmap_zones.yaml").read_text()
    keepout = '    - {name: keepout_layer, type: "costmap_2d::StaticLayer"}\n'
    inflation = '    - {name: inflation_layer, type: "costmap_2d::InflationLayer"}\n'
    (folder / "costmap_zones.yaml").write_text(text.replace(keepout, "", 1).replace(inflation, inflation + keepout, 1))
    obeys, why = costmap_rules.obeys_zones(str(folder), TOPIC)
    assert not obeys and "after the inflation layer" in why[0]
    assert costmap_rules.obeys_zones(SHIPPED, TOPIC, mapping=True)[0] is False
