"""The launch files under real roslaunch: args resolve, rosparam files load, nodes are unique.

The navigation stack (gmapping, amcl, move_base, map_server, rplidar_ros, hector_mapping, rviz)
is not packaged by Debian: stand-ins in tests/stub_packages let roslaunch and rospack resolve
``pkg=`` and ``$(find ...)`` exactly as on the robot, where the real ones are (their tiny nodes,
run by tests/test_stack_launched.py, publish what the real ones would; tf2_ros's stand-in adds
static_transform_publisher, which Debian's Python-only tf2_ros lacks).
server.launch is also started for real and must answer /health.
"""

import glob
import os
import re
import shutil
import signal
import subprocess

import pytest
import requests
import yaml

from tests.conftest import ROOT, free_port, stop_process, wait_for

STUBS = os.path.join(ROOT, "tests", "stub_packages")
LAUNCH_DIR = os.path.join(ROOT, "launch")

# Every launch file, and the arg combinations a user is told to use.
VARIANTS = [
    ("mapping.launch", []),
    ("mapping.launch", ["slam:=hector"]),
    ("navigation.launch", []),
    ("navigation.launch", ["server:=false", "map:=/tmp/some/map.yaml"]),
    ("navigation.launch", ["server:=false", "lidar:=false"]),  # the stack on flask-move-server --sim
    ("mapping.launch", ["server:=false", "lidar:=false"]),
    ("mapping.launch", ["move_base:=false"]),  # a robot too weak to run move_base beside gmapping
    ("server.launch", []),
    ("rviz.launch", []),
    ("rviz.launch", ["view:=mapping"]),
]


def ros_env(tmp_path=None):
    """Environment where our package and the stand-ins are on ROS_PACKAGE_PATH."""
    env = dict(os.environ)
    env["ROS_PACKAGE_PATH"] = os.pathsep.join([ROOT, STUBS])
    for name in list(env):
        if name.startswith("ROBOT_") or name in ("FLASK_MOVE_SERVER_CONFIG", "FLASK_MOVE_SERVER_MAP"):
            del env[name]  # the robot's environment must not leak into the defaults checked here
    if tmp_path is not None:
        env["ROS_HOME"] = str(tmp_path)
        env["ROS_LOG_DIR"] = str(tmp_path / "log")
    return env


def roslaunch(*args, env=None):
    """Run the real roslaunch command; returns stdout, fails the test with stderr on error."""
    exe = shutil.which("roslaunch") or "roslaunch"
    proc = subprocess.run([exe, *args], env=env or ros_env(), capture_output=True, text=True, timeout=60)
    # --dump-params exits 0 even when a file fails to load: anything on stderr is a failure.
    assert proc.returncode == 0 and not proc.stderr.strip(), "roslaunch {} failed:\n{}{}".format(
        " ".join(args), proc.stdout, proc.stderr)
    return proc.stdout


def launch_path(name):
    return os.path.join(LAUNCH_DIR, name)


def node_names(name, args=()):
    """Node names from ``roslaunch --nodes``."""
    return roslaunch("--nodes", launch_path(name), *args).split()


def dump_params(name, args=()):
    """All parameters from ``roslaunch --dump-params``: {"/node/key/...": value}."""
    return yaml.safe_load(roslaunch("--dump-params", launch_path(name), *args)) or {}


def all_launch_files():
    return sorted(os.path.basename(p) for p in glob.glob(os.path.join(LAUNCH_DIR, "*.launch")))


def test_a_missing_rosparam_file_fails_the_check(tmp_path):
    broken = tmp_path / "broken.launch"
    broken.write_text('<launch><node pkg="amcl" type="amcl" name="amcl">'
                      '<rosparam file="$(find flask_move_server)/config/amlc.yaml" command="load"/></node></launch>')
    with pytest.raises(AssertionError, match="amlc.yaml"):
        roslaunch("--dump-params", str(broken))


def test_every_launch_file_has_a_variant_checked():
    # sim.launch is the simulation's; it is parsed too (see test_nodes_are_unique_in_every_launch_file).
    ours = {name for name, _ in VARIANTS}
    assert set(all_launch_files()) - {"sim.launch"} <= ours


@pytest.mark.parametrize("name,args", VARIANTS, ids=lambda v: v if isinstance(v, str) else " ".join(v) or "-")
def test_args_resolve_and_params_load(name, args):
    nodes = node_names(name, args)
    params = dump_params(name, args)
    assert nodes, "no nodes in {}".format(name)
    assert len(nodes) == len(set(nodes)), "duplicate node names: {}".format(nodes)
    for key in params:
        assert "$(" not in key and "$(" not in str(params[key]), "unresolved substitution in {}".format(key)


@pytest.mark.parametrize("name", all_launch_files())
def test_nodes_are_unique_in_every_launch_file(name):
    nodes = node_names(name)
    assert nodes and len(nodes) == len(set(nodes)), nodes


def test_every_node_package_resolves_with_rospack():
    packages = set()
    for path in glob.glob(os.path.join(LAUNCH_DIR, "**", "*.launch"), recursive=True):
        with open(path, encoding="utf-8") as f:
            packages.update(re.findall(r'<node\b[^>]*\bpkg="([^"]+)"', f.read()))
    assert {"gmapping", "amcl", "move_base", "map_server", "rplidar_ros", "flask_move_server"} <= packages
    for package in sorted(packages):
        proc = subprocess.run(["rospack", "find", package], env=ros_env(), capture_output=True, text=True)
        assert proc.returncode == 0, "rospack cannot find {}: {}".format(package, proc.stderr)


def test_mapping_runs_gmapping_or_hector_with_the_lidar_move_base_and_the_driving_server():
    assert set(node_names("mapping.launch")) == {"/rplidar", "/base_link_to_laser", "/flask_move_server",
                                                 "/slam_gmapping", "/move_base"}
    assert "/hector_mapping" in node_names("mapping.launch", ["slam:=hector"])
    assert "/move_base" in node_names("mapping.launch", ["slam:=hector"])
    assert "/slam_gmapping" not in node_names("mapping.launch", ["slam:=hector"])
    assert set(node_names("mapping.launch", ["move_base:=false"])) == {
        "/rplidar", "/base_link_to_laser", "/flask_move_server", "/slam_gmapping"}
    params = dump_params("mapping.launch")
    assert params["/flask_move_server/drive/backend"] == "l298n"
    assert params["/rplidar/serial_port"] == "/dev/ttyUSB0" and params["/rplidar/serial_baudrate"] == 115200
    assert params["/rplidar/frame_id"] == "laser"


def test_navigation_under_systemd_leaves_the_server_to_its_own_unit():
    assert "/flask_move_server" in node_names("navigation.launch")
    nodes = node_names("navigation.launch", ["server:=false"])
    assert set(nodes) == {"/rplidar", "/base_link_to_laser", "/map_server", "/amcl", "/move_base"}


def test_navigation_args_reach_the_nodes():
    params = dump_params("navigation.launch", ["initial_pose_x:=1.5", "initial_pose_a:=-0.5", "lidar_port:=/dev/ttyS9"])
    assert params["/amcl/initial_pose_x"] == 1.5 and params["/amcl/initial_pose_a"] == -0.5
    assert params["/rplidar/serial_port"] == "/dev/ttyS9"
    assert params["/move_base/base_local_planner"] == "dwa_local_planner/DWAPlannerROS"
    assert params["/move_base/DWAPlannerROS/max_vel_y"] == 0.0  # skid-steer: no lateral motion


LAYER = {"static": {"name": "static_layer", "type": "costmap_2d::StaticLayer"},
         "keepout": {"name": "keepout_layer", "type": "costmap_2d::StaticLayer"},
         "obstacle": {"name": "obstacle_layer", "type": "costmap_2d::ObstacleLayer"},
         "inflation": {"name": "inflation_layer", "type": "costmap_2d::InflationLayer"}}
# Where mapping's move_base and navigation's differ: config/move_base_mapping.yaml, for a growing map, and
# config/costmap_zones.yaml, navigation's only.
GROWING_MAP = {
    "/move_base/NavfnROS/allow_unknown": (False, True),
    "/move_base/global_costmap/static_layer/subscribe_to_updates": (False, True),
    "/move_base/global_costmap/static_layer/first_map_only": (None, False),  # navigation: the default, false
    # no keepout layer while mapping (docs/zones.md): zones belong to a saved map
    "/move_base/global_costmap/plugins": ([LAYER["static"], LAYER["keepout"], LAYER["obstacle"], LAYER["inflation"]],
                                          [LAYER["static"], LAYER["obstacle"], LAYER["inflation"]]),
    "/move_base/local_costmap/plugins": ([LAYER["keepout"], LAYER["obstacle"], LAYER["inflation"]],
                                         [LAYER["obstacle"], LAYER["inflation"]]),
}
KEEPOUT = {"enabled": True, "map_topic": "keepout_map", "first_map_only": False, "subscribe_to_updates": False,
           "use_maximum": True, "trinary_costmap": True, "lethal_cost_threshold": 100, "unknown_cost_value": -1}
for _costmap, _unknown in (("global_costmap", True), ("local_costmap", False)):
    for _key, _value in dict(KEEPOUT, track_unknown_space=_unknown).items():
        GROWING_MAP["/move_base/{}/keepout_layer/{}".format(_costmap, _key)] = (_value, None)


def node_params(params, node):
    return {k: v for k, v in params.items() if k.startswith(node + "/")}


@pytest.mark.parametrize("args", [[], ["server:=false", "lidar:=false"], ["slam:=hector"]],
                         ids=lambda a: " ".join(a) or "-")
def test_mapping_s_move_base_is_navigation_s_with_the_growing_map_overrides(args):
    """Both include launch/include/move_base.launch: they differ by move_base_mapping.yaml's keys and the zones'
    layer only."""
    navigation = node_params(dump_params("navigation.launch"), "/move_base")
    mapping = node_params(dump_params("mapping.launch", args), "/move_base")
    differ = {k: (navigation.get(k), mapping.get(k)) for k in set(navigation) | set(mapping)
              if navigation.get(k) != mapping.get(k)}
    assert differ == GROWING_MAP
    assert len(navigation) > 50  # the whole move_base: costmaps, DWA, navfn, recoveries


def test_mapping_without_move_base_sets_none_of_its_params():
    assert node_params(dump_params("mapping.launch", ["move_base:=false"]), "/move_base") == {}


def test_frame_args_reach_mapping_s_move_base():
    params = dump_params("mapping.launch", ["map_frame:=world", "odom_frame:=wheels", "base_frame:=body"])
    assert params["/move_base/global_costmap/global_frame"] == "world"
    assert params["/move_base/local_costmap/global_frame"] == "wheels"
    assert params["/move_base/global_costmap/robot_base_frame"] == "body"
    assert params["/move_base/local_costmap/robot_base_frame"] == "body"


def launch_config(name, args=(), monkeypatch=None):
    """roslaunch's own parse of a launch file (nodes with package, type, args), in this process."""
    import roslaunch.config

    monkeypatch.setenv("ROS_PACKAGE_PATH", ros_env()["ROS_PACKAGE_PATH"])
    return roslaunch.config.load_config_default([(launch_path(name), list(args))], None, verbose=False)


def test_start_pose_comes_from_the_robot_environment():
    env = ros_env()
    env.update(ROBOT_START_X="2.5", ROBOT_START_YAW="1.57")
    params = yaml.safe_load(roslaunch("--dump-params", launch_path("navigation.launch"), env=env))
    assert (params["/amcl/initial_pose_x"], params["/amcl/initial_pose_y"], params["/amcl/initial_pose_a"]) == (
        2.5, 0.0, 1.57)


def test_lidar_and_laser_pose_come_from_the_robot_environment(monkeypatch):
    for name, value in dict(ROBOT_LIDAR_PORT="/dev/rplidar", ROBOT_LIDAR_BAUDRATE="256000",
                            ROBOT_LASER_X="0.07", ROBOT_LASER_YAW="3.14159").items():
        monkeypatch.setenv(name, value)
    for launch in ("mapping.launch", "navigation.launch"):
        config = launch_config(launch, [], monkeypatch)
        (tf,) = [n for n in config.nodes if n.name == "base_link_to_laser"]
        assert tf.args.split()[:4] == ["0.07", "0.0", "0.12", "3.14159"]
        params = {p.key: p.value for p in config.params.values()}
        assert params["/rplidar/serial_port"] == "/dev/rplidar" and params["/rplidar/serial_baudrate"] == 256000


def test_laser_pose_args_reach_the_static_transform(monkeypatch):
    config = launch_config("mapping.launch", ["laser_x:=0.05", "laser_yaw:=3.14159"], monkeypatch)
    (tf,) = [n for n in config.nodes if n.name == "base_link_to_laser"]
    assert (tf.package, tf.type) == ("tf2_ros", "static_transform_publisher")
    assert tf.args.split() == ["0.05", "0.0", "0.12", "3.14159", "0", "0", "base_link", "laser"]


def test_server_launch_args_become_private_params():
    params = dump_params("server.launch", ["port:=5050", "waypoints:=/var/lib/w.yaml", "config:=/etc/r.yaml",
                                           "motor_backend:=sim", "insecure:=true", "mdns:=false"])
    assert params["/flask_move_server/server/port"] == 5050
    assert params["/flask_move_server/waypoints/file"] == "/var/lib/w.yaml"
    assert params["/flask_move_server/config"] == "/etc/r.yaml"
    assert params["/flask_move_server/drive/backend"] == "sim"
    assert params["/flask_move_server/server/insecure"] is True
    assert params["/flask_move_server/mdns/enabled"] is False
    # Empty args keep the config file's values: no param at all.
    assert "/flask_move_server/server/port" not in dump_params("server.launch")


def test_server_node_executable_resolves():
    out = roslaunch("--args", "/flask_move_server", launch_path("server.launch"))
    assert os.path.join(ROOT, "scripts", "flask_move_server_node") in out


def test_server_launch_serves_health_through_real_roslaunch(ros_master, tmp_path):
    port = free_port()
    env = ros_env(tmp_path)
    env["ROS_MASTER_URI"] = ros_master
    proc = subprocess.Popen(
        [shutil.which("roslaunch") or "roslaunch", launch_path("server.launch"), "host:=127.0.0.1",
         "port:={}".format(port), "mdns:=false", "motor_backend:=none",
         "config:={}".format(os.path.join(ROOT, "config", "robot.yaml")),
         "waypoints:={}".format(tmp_path / "waypoints.yaml")],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
    )
    try:
        url = "http://127.0.0.1:{}/health".format(port)
        wait_for(lambda: _answers(url), timeout=60, message="the server started by roslaunch")
        assert requests.get(url, timeout=5).json()["status"] == "ok"
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
        stop_process(proc)
    assert not _answers("http://127.0.0.1:{}/health".format(port)), "server still running after roslaunch ended"


def _answers(url):
    try:
        return requests.get(url, timeout=2).status_code == 200
    except requests.RequestException:
        return False


@pytest.mark.parametrize("view", ["mapping", "navigation"])
def test_rviz_views_show_map_scan_robot_and_waypoints(view):
    with open(os.path.join(ROOT, "config", "rviz", view + ".rviz"), encoding="utf-8") as f:
        layout = yaml.safe_load(f)
    manager = layout["Visualization Manager"]
    topics = {d.get("Topic") or d.get("Marker Topic") for d in manager["Displays"]}
    assert {"/map", "/scan", "/odom", "/waypoint_markers"} <= topics
    assert "rviz/TF" in {d["Class"] for d in manager["Displays"]}
    assert manager["Global Options"]["Fixed Frame"] == "map"
    tools = {t["Class"]: t.get("Topic") for t in manager["Tools"]}
    assert tools["rviz/PublishPoint"] == "/clicked_point"  # record-waypoints listens there
    if view == "navigation":
        assert tools["rviz/SetGoal"] == "/move_base_simple/goal"
        assert tools["rviz/SetInitialPose"] == "/initialpose"
        assert {"/particlecloud", "/move_base/NavfnROS/plan", "/move_base/DWAPlannerROS/local_plan"} <= topics
