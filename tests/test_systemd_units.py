"""The systemd units: `systemd-analyze verify` passes, and they say what the robot needs.

verify checks that every ExecStart/ExecStopPost binary exists, so the units are verified as
installed by scripts/install into a temporary root, with /opt/flask-move-server rewritten to
that root. The commands the units run (ros-exec, drive.safe_stop) are run too.
"""

import glob
import os
import shutil
import subprocess
import sys

import pytest

from tests.conftest import ROOT

UNITS = sorted(os.path.basename(p) for p in glob.glob(os.path.join(ROOT, "systemd", "*.service")))


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    root = tmp_path_factory.mktemp("units_root")
    subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "install"), "--root", str(root), "--os", "debian"],
                   check=True, capture_output=True, timeout=300)
    return root


def rewritten(root, unit_text):
    return unit_text.replace("/opt/flask-move-server", os.path.join(str(root), "opt/flask-move-server"))


def verify(paths):
    exe = shutil.which("systemd-analyze")
    assert exe, "systemd-analyze missing: `make setup` installs the systemd package"
    proc = subprocess.run([exe, "verify", *paths], capture_output=True, text=True, timeout=60)
    # Bad values are only warnings (exit 0): any line about our units is a failure.
    complaints = [line for line in proc.stderr.splitlines() if ".service" in line]
    return proc.returncode, complaints


def test_units_verify(root, tmp_path):
    assert {"roscore.service", "robot-navigation.service", "flask-move-server.service"} <= set(UNITS)
    paths = []
    for unit in UNITS:
        with open(os.path.join(str(root), "etc/systemd/system", unit), encoding="utf-8") as f:
            path = tmp_path / unit
            path.write_text(rewritten(root, f.read()))
            paths.append(str(path))
    assert verify(paths) == (0, [])


def test_verify_catches_a_broken_unit(root, tmp_path):
    with open(os.path.join(ROOT, "systemd", "flask-move-server.service"), encoding="utf-8") as f:
        text = rewritten(root, f.read()).replace("Type=notify", "Type=notfy")
    path = tmp_path / "flask-move-server.service"
    path.write_text(text)
    _, complaints = verify([str(path)])
    assert any("notfy" in line for line in complaints)


def directives(unit):
    """{key: [values]} of a unit file (keys repeat, e.g. EnvironmentFile)."""
    values = {}
    with open(os.path.join(ROOT, "systemd", unit), encoding="utf-8") as f:
        for line in f:
            line = line.strip()
            if line and not line.startswith(("#", "[")):
                key, _, value = line.partition("=")
                values.setdefault(key, []).append(value)
    return values


def test_server_unit_is_watched_restarted_and_safe():
    unit = directives("flask-move-server.service")
    assert unit["Type"] == ["notify"] and int(unit["WatchdogSec"][0]) > 0
    assert unit["Restart"] == ["on-failure"]
    assert "network-online.target" in unit["Wants"][0] and "network-online.target" in unit["After"][0]
    assert unit["BindsTo"] == ["roscore.service"] and unit["PartOf"] == ["roscore.service"]
    assert unit["User"] == ["robot"] and set(unit["SupplementaryGroups"][0].split()) == {"gpio", "dialout"}
    env_files = " ".join(unit["EnvironmentFile"])
    assert "/etc/flask-move-server/ros.env" in env_files and "/etc/flask-move-server/token.env" in env_files
    assert "PrivateDevices" not in unit and "DevicePolicy" not in unit  # /dev/gpiomem, gpiochip, ttyUSB
    assert "flask_move_server.drive.safe_stop --config" in unit["ExecStopPost"][0]


def test_navigation_unit_leaves_the_server_to_its_own_unit():
    unit = directives("robot-navigation.service")
    assert "navigation.launch server:=false" in unit["ExecStart"][0]
    assert unit["BindsTo"] == ["roscore.service"] and unit["PartOf"] == ["roscore.service"]


def test_ros_exec_loads_the_robot_environment(root, tmp_path):
    etc = os.path.join(str(root), "etc/flask-move-server")
    setup = tmp_path / "setup.bash"
    setup.write_text("export ROS_DISTRO=noetic\nexport ROS_PACKAGE_PATH=/ws/share\n")
    env_file = tmp_path / "etc"
    shutil.copytree(etc, str(env_file))
    with open(str(env_file / "ros.env"), "a", encoding="utf-8") as f:
        f.write("ROS_SETUP={}\n".format(setup))
    env = {"PATH": os.environ["PATH"], "FLASK_MOVE_SERVER_ETC": str(env_file)}
    out = subprocess.run([os.path.join(str(root), "opt/flask-move-server/bin/ros-exec"), "env"], env=env,
                         capture_output=True, text=True, timeout=30, check=True).stdout
    seen = dict(line.split("=", 1) for line in out.splitlines() if "=" in line)
    assert seen["ROS_DISTRO"] == "noetic"
    assert seen["ROS_PACKAGE_PATH"] == "/opt/flask-move-server/share:/ws/share"
    assert seen["FLASK_MOVE_SERVER_CONFIG"] == "/etc/flask-move-server/robot.yaml"
    assert len(seen["FLASK_MOVE_SERVER_TOKEN"]) >= 32


def test_ros_exec_says_when_ros_is_missing(root, tmp_path):
    env = {"PATH": os.environ["PATH"], "FLASK_MOVE_SERVER_CONFIG": "x", "ROS_SETUP": str(tmp_path / "nope.bash")}
    proc = subprocess.run([os.path.join(str(root), "opt/flask-move-server/bin/ros-exec"), "true"], env=env,
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode == 1 and "nope.bash does not exist" in proc.stderr


def test_exec_stop_post_names_what_to_install_without_gpio(root):
    python = os.path.join(str(root), "opt/flask-move-server/bin/python")
    proc = subprocess.run([python, "-m", "flask_move_server.drive.safe_stop", "--config",
                           os.path.join(str(root), "etc/flask-move-server/robot.yaml")],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1 and "RPi.GPIO" in proc.stderr


def test_server_unit_stops_its_stack_with_it():
    from flask_move_server.config import ModesConfig

    unit = directives("flask-move-server.service")
    assert unit["KillMode"] == ["control-group"]  # roslaunch and every node live in the unit's cgroup
    # The server's own stop (SIGINT, stop_timeout, SIGTERM 2 s, SIGKILL) fits before systemd's.
    assert int(unit["TimeoutStopSec"][0]) >= ModesConfig().stop_timeout + 10
    assert "roslaunch" not in unit["ExecStart"][0]  # the server starts the stack of the mode asked for


def test_manual_stack_units_say_they_are_for_stack_none():
    for name in ("robot-navigation.service", "robot-mapping.service"):
        with open(os.path.join(ROOT, "systemd", name), encoding="utf-8") as f:
            assert "modes.stack: none" in f.read()
