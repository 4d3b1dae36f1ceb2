"""scripts/install --root DIR: the laid-out tree, idempotence, operator files kept, token 0600.

The installer runs for real (a real venv with the package pip-installed, real files), only
into a temporary root: --root promises no apt, no user changes and no systemctl.
"""

import hashlib
import os
import stat
import subprocess
import sys

import pytest
import yaml

from flask_move_server import config as config_mod
from tests.conftest import ROOT

INSTALL = os.path.join(ROOT, "scripts", "install")


def install(root):
    proc = subprocess.run([sys.executable, INSTALL, "--root", str(root), "--os", "debian"],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return proc.stdout


def snapshot(root):
    """Every path under root with its type, mode and content hash (or link target)."""
    tree = {}
    for base, dirs, files in os.walk(str(root)):
        for name in dirs + files:
            path = os.path.join(base, name)
            info = os.lstat(path)
            if stat.S_ISLNK(info.st_mode):
                what = ("link", os.readlink(path))
            elif stat.S_ISDIR(info.st_mode):
                what = ("dir", stat.S_IMODE(info.st_mode))
            else:
                with open(path, "rb") as f:
                    what = ("file", stat.S_IMODE(info.st_mode), hashlib.sha256(f.read()).hexdigest())
            tree[os.path.relpath(path, str(root))] = what
    return tree


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    root = tmp_path_factory.mktemp("robot_root")
    checkout_before = sorted(os.listdir(ROOT))
    first = install(root)
    assert sorted(os.listdir(ROOT)) == checkout_before, "the installer wrote into the checkout"
    return root, first


def token_of(root):
    with open(os.path.join(str(root), "etc/flask-move-server/token.env"), encoding="utf-8") as f:
        key, _, value = f.read().strip().partition("=")
    assert key == "FLASK_MOVE_SERVER_TOKEN"
    return value


def test_lays_out_the_robot(installed):
    root, _ = installed
    for path in ("opt/flask-move-server/bin/python", "opt/flask-move-server/bin/flask-move-server",
                 "opt/flask-move-server/bin/ros-exec", "etc/flask-move-server/robot.yaml",
                 "etc/flask-move-server/ros.env", "var/lib/flask-move-server/waypoints.yaml",
                 "var/lib/flask-move-server/maps", "etc/systemd/system/flask-move-server.service",
                 "etc/systemd/system/roscore.service", "etc/systemd/system/robot-navigation.service",
                 "opt/flask-move-server/share/flask_move_server/launch/navigation.launch",
                 "opt/flask-move-server/share/flask_move_server/config/amcl.yaml"):
        assert os.path.exists(os.path.join(str(root), path)), path
    with open(os.path.join(str(root), "opt/flask-move-server/pyvenv.cfg"), encoding="utf-8") as f:
        assert "include-system-site-packages = true" in f.read()  # so the venv sees rospy


def test_commands_are_on_the_path_and_login_shells_get_ros(installed, tmp_path):
    root, _ = installed
    for name in ("flask-move-server", "robotctl", "record-waypoints", "ros-exec"):
        link = os.path.join(str(root), "usr/local/bin", name)
        assert os.readlink(link) == "/opt/flask-move-server/bin/" + name
        assert os.path.exists(os.path.join(str(root), "opt/flask-move-server/bin", name))
    # The profile script, sourced by a POSIX shell with this root's env file and a ROS setup.
    profile = (root / "etc/profile.d/flask-move-server.sh").read_text()
    etc = str(root / "etc/flask-move-server")
    setup = tmp_path / "setup.sh"
    setup.write_text("ROS_DISTRO=noetic; export ROS_DISTRO\n")
    with open(os.path.join(etc, "ros.env"), encoding="utf-8") as f:
        env_text = f.read().replace("ROS_SETUP=/opt/ros-catkin/install_isolated/setup.bash",
                                    "ROS_SETUP={}".format(tmp_path / "setup.bash"))
    (tmp_path / "ros.env").write_text(env_text)
    script = profile.replace("/etc/flask-move-server/ros.env", str(tmp_path / "ros.env"))
    out = subprocess.run(["sh", "-c", script + "\nenv"], capture_output=True, text=True, timeout=30,
                         env={"PATH": os.environ["PATH"], "ROS_HOME": "/home/me/.ros"}).stdout
    seen = dict(line.split("=", 1) for line in out.splitlines() if "=" in line)
    assert seen["ROS_DISTRO"] == "noetic" and seen["ROS_MASTER_URI"] == "http://localhost:11311"
    assert seen["ROS_PACKAGE_PATH"].startswith("/opt/flask-move-server/share")
    assert seen["ROS_HOME"] == "/home/me/.ros"  # the units' log folder is robot's, not the login user's


def test_token_is_0600_and_printed_once(installed, tmp_path):
    root, first = installed
    token = token_of(root)
    assert len(token) >= 32
    assert stat.S_IMODE(os.stat(os.path.join(str(root), "etc/flask-move-server/token.env")).st_mode) == 0o600
    assert first.count(token) == 1
    again = install(root)
    assert token not in again and token_of(root) == token


def test_installed_config_is_valid_and_drives_the_l298n(installed):
    root, _ = installed
    config = config_mod.load(os.path.join(str(root), "etc/flask-move-server/robot.yaml"))
    assert config.drive.backend == "l298n"
    assert config.waypoints.file == "/var/lib/flask-move-server/waypoints.yaml"
    with open(os.path.join(str(root), "var/lib/flask-move-server/waypoints.yaml"), encoding="utf-8") as f:
        assert yaml.safe_load(f) == {"waypoints": {}}


def test_installed_package_runs_from_the_venv(installed):
    root, _ = installed
    proc = subprocess.run([os.path.join(str(root), "opt/flask-move-server/bin/flask-move-server"), "--version"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and "flask-move-server" in proc.stdout


def test_installed_launch_files_resolve_with_roslaunch(installed):
    from tests.test_launch import STUBS

    root, _ = installed
    env = dict(os.environ, ROS_PACKAGE_PATH=os.pathsep.join([os.path.join(str(root), "opt/flask-move-server/share"),
                                                             STUBS]))
    proc = subprocess.run(["roslaunch", "--nodes", "flask_move_server", "navigation.launch", "server:=false"],
                          env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "/move_base" in proc.stdout.split()


def test_second_run_changes_nothing(installed):
    root, _ = installed
    before = snapshot(root)
    out = install(root)
    assert "nothing to change" in out
    assert snapshot(root) == before


def test_operator_files_survive_a_rerun(tmp_path):
    root = tmp_path / "root"
    install(root)
    edits = {
        "etc/flask-move-server/robot.yaml": "server:\n  port: 8080\n",
        "etc/flask-move-server/ros.env": "ROS_MASTER_URI=http://robot.local:11311\n",
        "var/lib/flask-move-server/waypoints.yaml": "waypoints:\n  kitchen: [1.0, 2.0, 0.5]\n",
        "var/lib/flask-move-server/maps/map.yaml": "image: map.pgm\nresolution: 0.05\n",
        "etc/flask-move-server/token.env": "FLASK_MOVE_SERVER_TOKEN=operator-chosen-secret\n",
    }
    for path, text in edits.items():
        (root / path).write_text(text)
    os.chmod(str(root / "etc/flask-move-server/token.env"), 0o644)  # an operator slip
    install(root)
    for path, text in edits.items():
        assert (root / path).read_text() == text, path
    assert stat.S_IMODE(os.stat(str(root / "etc/flask-move-server/token.env")).st_mode) == 0o600


def test_an_updated_unit_is_replaced(installed):
    root, _ = installed
    unit = os.path.join(str(root), "etc/systemd/system/roscore.service")
    with open(unit, "a", encoding="utf-8") as f:
        f.write("# stale\n")
    out = install(root)
    assert "roscore.service" in out
    with open(unit, encoding="utf-8") as f, open(os.path.join(ROOT, "systemd/roscore.service"), encoding="utf-8") as g:
        assert f.read() == g.read()


def installer_module():
    """scripts/install imported (it has no .py suffix), for its pure helpers."""
    import importlib.machinery
    import importlib.util

    loader = importlib.machinery.SourceFileLoader("flask_move_server_install", INSTALL)
    module = importlib.util.module_from_spec(importlib.util.spec_from_loader(loader.name, loader))
    loader.exec_module(module)
    return module


def test_the_server_owns_the_stack_so_an_upgrade_retires_the_navigation_unit(installed):
    root, _ = installed
    with open(os.path.join(str(root), "etc/flask-move-server/robot.yaml"), encoding="utf-8") as f:
        commands = installer_module().systemctl_commands(f.read())
    enabled = [c for c in commands if c[1] == "enable"]
    assert enabled == [["systemctl", "enable", "roscore.service", "flask-move-server.service"]]
    assert ["systemctl", "disable", "--now", "robot-navigation.service", "robot-mapping.service"] in commands
    assert commands[-1] == ["systemctl", "restart", "flask-move-server.service"]


@pytest.mark.parametrize("text", ["modes:\n  # who runs it\n  start_timeout: 5\n  stack: none   # mine\n",
                                  "modes: {stack: none, restarts: 1}\n"])
def test_with_stack_none_the_operators_navigation_unit_is_left_alone(text):
    commands = installer_module().systemctl_commands(text)
    assert not any("robot-navigation.service" in c for c in commands)


def test_a_stack_key_of_another_section_is_not_taken_for_modes():
    assert installer_module().modes_stack("maps:\n  stack: none\nmodes:\n  restarts: 1\n") == "auto"
