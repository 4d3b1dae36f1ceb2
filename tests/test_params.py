"""Every parameter our launch files and config/*.yaml set is one its Noetic package reads.

The tables in tests/data/ros_params/ come from each package's documentation. A misspelt or
outdated name would otherwise be ignored by the node, which silently keeps its default (an
8 m lidar clipped at 80 m, a skid-steer asked to strafe): here it fails a test instead.
The server node's private params are checked against the server's own config schema.
"""

import glob
import os

import pytest
import yaml

from flask_move_server import config as config_mod
from flask_move_server.core.errors import ConfigError
from tests.conftest import ROOT
from tests.test_launch import VARIANTS, dump_params, launch_config

TABLES_DIR = os.path.join(ROOT, "tests", "data", "ros_params")
# Files in config/ that are not ROS node parameters.
NOT_ROS_PARAMS = {"robot.yaml"}


def load_tables():
    tables = {}
    for path in glob.glob(os.path.join(TABLES_DIR, "*.yaml")):
        with open(path, encoding="utf-8") as f:
            table = yaml.safe_load(f)
        tables[table["package"]] = table
    return tables


TABLES = load_tables()


def nest(flat, node):
    """``{"/node/a/b": 1}`` → ``{"a": {"b": 1}}`` for one node's private params."""
    tree = {}
    prefix = "/{}/".format(node)
    for key, value in flat.items():
        if not key.startswith(prefix):
            continue
        *parents, leaf = key[len(prefix):].split("/")
        branch = tree
        for part in parents:
            branch = branch.setdefault(part, {})
        branch[leaf] = value
    return tree


def check_names(tree, table, where):
    """Problems with the keys of ``tree`` for a node or plugin described by ``table``."""
    problems = check_conditions(tree, table, where)
    known = set(table.get("parameters", []))
    namespaces = dict(table.get("namespaces", {}))
    namespaces.update(recovery_namespaces(tree, table, where, problems))
    for key, value in tree.items():
        name = "{}/{}".format(where, key)
        if key in namespaces:
            problems += check_package(value, namespaces[key], name)
        elif key in table.get("deprecated", {}):
            problems.append("{}: outdated name, {} reads {!r}".format(name, table["package"], table["deprecated"][key]))
        elif key not in known:
            problems.append("{}: not a parameter of {} ({})".format(name, table["package"], table["source"]))
    return problems


def recovery_namespaces(tree, table, where, problems):
    """move_base: each recovery_behaviors entry's ``~<name>/`` namespace, read by its type's table."""
    types = table.get("recoveries", {})
    namespaces = {}
    for entry in tree.get("recovery_behaviors", []) if types else []:
        if entry.get("type") in types:
            namespaces[entry["name"]] = types[entry["type"]]
        else:
            problems.append("{}/recovery_behaviors: unknown recovery type {!r}".format(where, entry.get("type")))
    return namespaces


def check_conditions(tree, table, where):
    """Keys a node reads only under some setting of another key (amcl's laser models)."""
    problems = []
    for setting, rule in table.get("only_with", {}).items():
        value = tree.get(setting, rule["default"])
        for key, settings in rule["keys"].items():
            if key in tree and value not in settings:
                problems.append("{}/{}: does nothing with {} {} (read only with {})".format(
                    where, key, setting, value, " or ".join(settings)))
    return problems


def check_package(tree, package, where):
    if package == "costmap_2d":
        return check_costmap(tree, where)
    return check_names(tree, TABLES[package], where)


def check_costmap(tree, where):
    """A costmap: its own keys, then each plugin layer's keys, then each observation source."""
    table = TABLES["costmap_2d"]
    layers = {p["name"]: p["type"] for p in tree.get("plugins", [])}
    flat = {k: v for k, v in tree.items() if not isinstance(v, dict)}
    problems = check_names(flat, table, where)
    for name, value in tree.items():
        if not isinstance(value, dict):
            continue
        if name not in layers:
            problems.append("{}/{}: not a layer in this costmap's plugins {}".format(where, name, sorted(layers)))
        elif layers[name] not in table["layers"]:
            problems.append("{}/{}: unknown layer type {}".format(where, name, layers[name]))
        else:
            problems += check_layer(value, table["layers"][layers[name]], "{}/{}".format(where, name))
    return problems


def check_layer(tree, known, where):
    problems = []
    sources = str(tree.get("observation_sources", "")).split()
    for key, value in tree.items():
        if key in sources and isinstance(value, dict):
            bad = sorted(set(value) - set(TABLES["costmap_2d"]["observation_source"]))
            problems += ["{}/{}/{}: not an observation source parameter".format(where, key, b) for b in bad]
        elif key not in known:
            problems.append("{}/{}: not a parameter of this costmap layer".format(where, key))
    missing = [s for s in sources if not isinstance(tree.get(s), dict)]
    problems += ["{}: observation source {!r} has no parameters".format(where, s) for s in missing]
    return problems


def check_server(tree, where):
    """The server node: its private params must build a valid config (unknown keys rejected)."""
    tree = dict(tree)
    tree.pop("config", None)
    try:
        config_mod.build(config_mod.Config, tree, source=where)
    except ConfigError as exc:
        return [str(exc)]
    return []


def check_node(flat, node, package):
    tree = nest(flat, node)
    if package == "flask_move_server":
        return check_server(tree, "/" + node)
    if package not in TABLES:
        return ["/{}/{}: {} has no parameter table".format(node, k, package) for k in tree]
    return check_package(tree, package, "/" + node)


def problems_in(name, args, monkeypatch):
    flat = dump_params(name, args)
    nodes = {n.name: n.package for n in launch_config(name, args, monkeypatch).nodes}
    problems = []
    for node, package in nodes.items():
        problems += check_node(flat, node, package)
    owned = tuple("/{}/".format(n) for n in nodes)
    problems += ["{}: belongs to no node of {}".format(k, name) for k in flat
                 if not k.startswith(owned) and k not in ("/rosdistro", "/rosversion")]
    return problems


@pytest.mark.parametrize("name,args", VARIANTS, ids=lambda v: v if isinstance(v, str) else " ".join(v) or "-")
def test_every_launched_parameter_is_read_by_its_node(name, args, monkeypatch):
    assert problems_in(name, args, monkeypatch) == []


def test_every_ros_config_file_is_loaded_by_a_launch_file():
    launch_text = ""
    for path in glob.glob(os.path.join(ROOT, "launch", "**", "*.launch"), recursive=True):
        with open(path, encoding="utf-8") as f:
            launch_text += f.read()
    for path in glob.glob(os.path.join(ROOT, "config", "*.yaml")):
        base = os.path.basename(path)
        if base in NOT_ROS_PARAMS or base.startswith("waypoints"):
            continue
        assert "config/" + base in launch_text, "{} is not loaded by any launch file, so it is not checked".format(base)


def test_a_typo_in_a_parameter_name_is_caught():
    flat = {"/slam_gmapping/maxUrange": 6.0, "/slam_gmapping/maxUrnage": 6.0}
    (problem,) = check_node(flat, "slam_gmapping", "gmapping")
    assert "maxUrnage" in problem and "gmapping" in problem


def test_an_outdated_dwa_name_is_caught_with_its_replacement():
    flat = {"/move_base/DWAPlannerROS/acc_lim_th": 2.0, "/move_base/DWAPlannerROS/acc_lim_theta": 2.0}
    (problem,) = check_node(flat, "move_base", "move_base")
    assert "acc_lim_th" in problem and "acc_lim_theta" in problem


def test_costmap_layers_and_observation_sources_are_checked():
    flat = {
        "/move_base/local_costmap/plugins": [{"name": "obstacles", "type": "costmap_2d::ObstacleLayer"}],
        "/move_base/local_costmap/obstacles/observation_sources": "scan",
        "/move_base/local_costmap/obstacles/scan/topic": "scan",
        "/move_base/local_costmap/obstacles/scan/max_range": 8.0,
        "/move_base/local_costmap/inflation/inflation_radius": 0.3,
    }
    problems = check_node(flat, "move_base", "move_base")
    assert len(problems) == 2
    assert any("scan/max_range" in p for p in problems)
    assert any("inflation" in p and "not a layer" in p for p in problems)


def test_a_wrong_server_param_is_caught():
    flat = {"/flask_move_server/server/prot": 5000}
    (problem,) = check_node(flat, "flask_move_server", "flask_move_server")
    assert "server.prot" in problem


def test_local_planner_asks_only_what_the_drive_can_do():
    with open(os.path.join(ROOT, "config", "dwa_local_planner.yaml"), encoding="utf-8") as f:
        dwa = yaml.safe_load(f)["DWAPlannerROS"]
    robot = config_mod.load(os.path.join(ROOT, "config", "robot.yaml"))
    drive, teleop = robot.drive, robot.teleop
    assert dwa["max_vel_y"] == dwa["min_vel_y"] == dwa["acc_lim_y"] == 0.0  # skid-steer: no strafing
    assert dwa["max_vel_x"] <= min(drive.max_linear, teleop.max_linear)
    assert abs(dwa["min_vel_x"]) <= dwa["max_vel_x"]
    assert 0 < dwa["min_vel_theta"] < dwa["max_vel_theta"] <= min(drive.max_angular, teleop.max_angular)
    # The drive ramps at its own limits: a planner assuming faster ramps mispredicts every trajectory.
    assert dwa["acc_lim_x"] <= drive.max_linear_accel
    assert dwa["acc_lim_theta"] <= drive.max_angular_accel
    # Below min_vel_trans a wheel sits in the min_duty deadband: DWA must treat it as stopped.
    assert dwa["min_vel_trans"] >= dwa["trans_stopped_vel"] > 0
