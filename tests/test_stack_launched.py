"""The roslaunch stack backend against real roslaunch, a real master and the stub nodes.

The stub packages (tests/stub_packages) stand in for gmapping, map_server, amcl, move_base,
rplidar_ros and tf2_ros's static_transform_publisher. What is checked is what a user would
notice on the robot: the map served is the one asked for, a switch leaves nothing of the old
stack running, a dead part is reported in words, and a killed server leaves no stack behind.
Processes are found here independently of the backend's own bookkeeping: every process whose
environment points at this test's ROS master.
"""

import os
import re
import signal
import subprocess
import sys
import threading
import time
import xmlrpc.client

import pytest

from flask_move_server.config import ModesConfig
from flask_move_server.core.errors import StackFailed
from flask_move_server.maps import mapfile
from flask_move_server.modes import child, readiness
from flask_move_server.modes.launched import LaunchedStack
from tests.conftest import ROOT, default_sigint, wait_for
from tests.test_launch import STUBS, ros_env

# Each cycle starts three stacks (~2-5 s each on a loaded 2-core machine); STACK_CYCLES=20 for the long run.
CYCLES = int(os.environ.get("STACK_CYCLES", "3"))


@pytest.fixture
def stack_env(ros_master, tmp_path, monkeypatch):
    """The server's environment on the robot (roslaunch runs in it): our package and the stubs findable."""
    env = ros_env(tmp_path)
    env.update(ROS_MASTER_URI=ros_master, ROS_IP="127.0.0.1")
    for name in set(os.environ) - set(env):
        monkeypatch.delenv(name)
    for name, value in env.items():
        monkeypatch.setenv(name, value)
    return env


def make_stack(env, **modes):
    modes.setdefault("start_timeout", 40.0)
    modes.setdefault("stop_timeout", 5.0)
    return LaunchedStack(ModesConfig(**modes), master_uri=env["ROS_MASTER_URI"])


def stack_processes(master_uri):
    """{pid: command line} of every live process (not this one) whose ROS_MASTER_URI is ``master_uri``."""
    wanted = "ROS_MASTER_URI={}".format(master_uri).encode()
    found = {}
    for name in os.listdir("/proc"):
        if not name.isdigit() or int(name) == os.getpid():
            continue
        try:
            with open("/proc/{}/environ".format(name), "rb") as f:
                environ = f.read().split(b"\0")
            with open("/proc/{}/stat".format(name), "rb") as f:
                state = f.read().rsplit(b")", 1)[1].split()[0]
            with open("/proc/{}/cmdline".format(name), "rb") as f:
                cmdline = f.read().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if wanted in environ and state not in (b"Z", b"X"):
            found[int(name)] = cmdline
    return found


def nothing_left(master_uri, timeout=0.0):
    """True when no process of ours talks to the master (after waiting up to ``timeout``)."""
    deadline = time.monotonic() + timeout
    while stack_processes(master_uri) and time.monotonic() < deadline:
        time.sleep(0.1)
    return not stack_processes(master_uri)


def served_map_width(ros_node):
    import rospy
    from nav_msgs.msg import OccupancyGrid

    return rospy.wait_for_message("/map", OccupancyGrid, timeout=10).info.width


def save_map(folder, name, width, height):
    mapfile.save(str(folder), name, mapfile.Grid(width, height, 0.05, -0.5, -0.5, bytes(width * height)))
    return str(folder / (name + ".yaml"))


@pytest.mark.timeout(60 + 40 * CYCLES)
def test_switching_modes_leaves_nothing_of_the_previous_stack(stack_env, ros_node, tmp_path):
    maps = [save_map(tmp_path, "flat", 31, 21), save_map(tmp_path, "garage", 43, 11)]
    master_uri = stack_env["ROS_MASTER_URI"]
    stack = make_stack(stack_env)
    try:
        for _ in range(CYCLES):
            previous = set()
            for mode, yaml_path, width in (("mapping", None, 20), ("navigation", maps[0], 31),
                                           ("navigation", maps[1], 43)):
                stack.start(mode, yaml_path, on_exit=pytest.fail)
                now = stack_processes(master_uri)
                assert not previous & set(now), "left running: {}".format([now[p] for p in previous & set(now)])
                assert served_map_width(ros_node) == width
                previous = set(now)
            stack.start("idle", None)
            assert nothing_left(master_uri), stack_processes(master_uri)
    finally:
        stack.close()
    assert nothing_left(master_uri), stack_processes(master_uri)


def test_mapping_waits_for_move_base_on_the_map_gmapping_grows(stack_env):
    """mapping.launch runs move_base (launch/include/move_base.launch): ready once its action answers,
    which the real move_base does only after its global costmap got the first /map."""
    master = xmlrpc.client.ServerProxy(stack_env["ROS_MASTER_URI"])
    with make_stack(stack_env) as stack:
        stack.start("mapping", None, on_exit=pytest.fail)
        assert stack.serves_goals("mapping")
        assert any("__name:=move_base" in cmd for cmd in stack_processes(stack_env["ROS_MASTER_URI"]).values())
        assert master.getParam("/test", "/move_base/map_size")[2] == [20, 10]  # the stub gmapping's map
        assert master.getParam("/test", "/move_base/NavfnROS/allow_unknown")[2] is True
    assert nothing_left(stack_env["ROS_MASTER_URI"])


OWN_MAPPING = """<launch>
  <arg name="server" default="true"/>
  <arg name="lidar" default="true"/>
  <include file="$(find flask_move_server)/launch/mapping.launch">
    <arg name="server" value="$(arg server)"/>
    <arg name="lidar" value="$(arg lidar)"/>
    <arg name="move_base" value="false"/>
  </include>
</launch>
"""


def test_a_mapping_launch_file_without_move_base_is_ready_without_it(stack_env, tmp_path, monkeypatch):
    """A robot too weak for move_base beside gmapping: the owner's launch file includes mapping.launch
    with move_base:=false. The stack is ready on /map alone and says it takes no goals."""
    package = tmp_path / "weak_robot"
    (package / "launch").mkdir(parents=True)
    (package / "package.xml").write_text('<package format="2"><name>weak_robot</name><version>0.0.0</version>'
                                         '<description>d</description><maintainer email="a@b.c">a</maintainer>'
                                         '<license>BSD</license></package>')
    (package / "launch" / "mapping.launch").write_text(OWN_MAPPING)
    monkeypatch.setenv("ROS_PACKAGE_PATH", os.pathsep.join([os.environ["ROS_PACKAGE_PATH"], str(tmp_path)]))
    with make_stack(stack_env, mapping_launch="weak_robot mapping.launch") as stack:
        stack.start("mapping", None, on_exit=pytest.fail)
        assert not stack.serves_goals("mapping") and stack.serves_goals("navigation")
        names = " ".join(stack_processes(stack_env["ROS_MASTER_URI"]).values())
        assert "__name:=slam_gmapping" in names and "__name:=move_base" not in names
    assert nothing_left(stack_env["ROS_MASTER_URI"])


def test_the_stack_outlives_the_thread_that_started_it(stack_env):
    # The mode manager starts a stack from a switch thread that ends once the stack runs; the
    # parent-death signal follows the thread that started roslaunch, not the server process.
    stack = make_stack(stack_env)
    try:
        starter = threading.Thread(target=stack.start, args=("mapping", None))
        starter.start()
        starter.join(60)
        started = stack_processes(stack_env["ROS_MASTER_URI"])
        time.sleep(1.5)  # a SIGTERM to roslaunch at the thread's end has it stop its nodes within this
        assert stack.running and stack_processes(stack_env["ROS_MASTER_URI"]) == started
    finally:
        stack.close()
    assert nothing_left(stack_env["ROS_MASTER_URI"])


def test_navigation_without_a_map_uses_the_launch_files_default(stack_env, ros_node, tmp_path, monkeypatch):
    monkeypatch.setenv("FLASK_MOVE_SERVER_MAP", save_map(tmp_path, "default", 17, 9))
    with make_stack(stack_env) as stack:
        stack.start("navigation", None)
        assert served_map_width(ros_node) == 17
    assert nothing_left(stack_env["ROS_MASTER_URI"])


def test_a_part_that_dies_is_reported_once_in_words(stack_env):
    reports = []
    stack = make_stack(stack_env)
    try:
        stack.start("navigation", os.path.join(ROOT, "config", "maps", "demo.yaml"), on_exit=reports.append)
        (move_base,) = [pid for pid, cmd in stack_processes(stack_env["ROS_MASTER_URI"]).items()
                        if "/move_base/move_base" in cmd]
        os.kill(move_base, signal.SIGKILL)
        wait_for(lambda: reports, timeout=15, message="on_exit")
        time.sleep(1.0)  # a second report would come from the same watcher within this
        assert len(reports) == 1
        assert re.match(r"the navigation stack's move_base node was killed \(signal 9\); its log: {}/\S+/move_base-\d+"
                        r"\.log$".format(re.escape(stack_env["ROS_LOG_DIR"])), reports[0]), reports[0]
    finally:
        stack.close()
    assert nothing_left(stack_env["ROS_MASTER_URI"])


def test_a_respawning_part_is_not_the_stack_dying(stack_env):
    reports = []
    stack = make_stack(stack_env)
    try:
        stack.start("mapping", None, on_exit=reports.append)
        (lidar,) = [pid for pid, cmd in stack_processes(stack_env["ROS_MASTER_URI"]).items() if "rplidarNode" in cmd]
        os.kill(lidar, signal.SIGKILL)  # launch/include/lidar.launch: respawn="true" (a USB hiccup)
        wait_for(lambda: any("[rplidar-1] process has died" in line for line in stack._proc.last_lines(20)),
                 timeout=15, message="roslaunch to notice the lidar died")
        time.sleep(1.0)
        assert reports == []
    finally:
        stack.close()


def test_a_missing_package_is_named_with_the_command_that_installs_it(stack_env, tmp_path, monkeypatch):
    stubs = tmp_path / "stubs"
    stubs.mkdir()
    for name in os.listdir(STUBS):
        if name != "gmapping":
            os.symlink(os.path.join(STUBS, name), str(stubs / name))
    monkeypatch.setenv("ROS_PACKAGE_PATH", os.pathsep.join([ROOT, str(stubs)]))
    stack = make_stack(stack_env)
    with pytest.raises(StackFailed, match=r"^gmapping is not installed: sudo apt install ros-noetic-gmapping$"):
        stack.start("mapping", None)
    stack.close()
    assert nothing_left(stack_env["ROS_MASTER_URI"])


def test_a_part_that_never_appears_is_named_after_the_timeout(stack_env):
    stack = LaunchedStack(ModesConfig(start_timeout=3.0, stop_timeout=5.0), map_topic="never_published",
                          master_uri=stack_env["ROS_MASTER_URI"])
    with pytest.raises(StackFailed, match=r"the mapping stack started, but after 3 s nothing of it publishes "
                                          r"/never_published"):
        stack.start("mapping", None)
    stack.close()
    assert nothing_left(stack_env["ROS_MASTER_URI"])


def test_a_map_server_that_cannot_read_the_map_fails_the_start_with_its_reason(stack_env, tmp_path):
    stack = make_stack(stack_env)
    with pytest.raises(StackFailed, match=r"map_server node exited with status 1 \(.*could not open the map"):
        stack.start("navigation", str(tmp_path / "gone.yaml"))
    stack.close()
    assert nothing_left(stack_env["ROS_MASTER_URI"])


def test_no_master_no_stack(stack_env, monkeypatch):
    from tests.conftest import free_port

    stack_env["ROS_MASTER_URI"] = "http://127.0.0.1:{}".format(free_port())
    monkeypatch.setenv("ROS_MASTER_URI", stack_env["ROS_MASTER_URI"])
    stack = make_stack(stack_env)
    with pytest.raises(StackFailed, match="no ROS master answers at http://127.0.0.1:"):
        stack.start("mapping", None)
    stack.close()
    assert nothing_left(stack_env["ROS_MASTER_URI"])  # roslaunch would have started a master of its own


DRIVER = """
import sys
from flask_move_server.config import ModesConfig
from flask_move_server.modes.launched import LaunchedStack
stack = LaunchedStack(ModesConfig(start_timeout=40.0, stop_timeout=5.0))
stack.start("mapping", None)
print("ready", flush=True)
sys.stdin.read()
"""


def test_a_killed_server_leaves_no_stack_behind(stack_env):
    driver = subprocess.Popen([sys.executable, "-c", DRIVER], env=stack_env, cwd=ROOT, stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        assert driver.stdout.readline().strip() == "ready"
        assert len(stack_processes(stack_env["ROS_MASTER_URI"])) > 3  # the driver, roslaunch and its nodes
        driver.kill()
        driver.wait()
        assert nothing_left(stack_env["ROS_MASTER_URI"], timeout=20), stack_processes(stack_env["ROS_MASTER_URI"])
    finally:
        if driver.poll() is None:
            driver.kill()
        child.stop_tree(lambda: set(stack_processes(stack_env["ROS_MASTER_URI"])), 1.0)


ROSLAUNCH_LINE = "ERROR: cannot launch node of type [gmapping/slam_gmapping]: gmapping"


def test_roslaunchs_own_cannot_launch_line_reads_as_an_apt_command():
    proc = child.StackProcess(["true"])
    proc._note(ROSLAUNCH_LINE.strip())
    assert list(proc.events) == [["cannot_launch", "gmapping", "slam_gmapping", "gmapping"]]
    assert readiness.cannot_launch_message(*proc.events[0][1:]) == (
        "gmapping is not installed: sudo apt install ros-noetic-gmapping")
    assert readiness.cannot_launch_message("move_base", "move_base", "Cannot locate node of type [move_base]") == (
        "move_base has no node move_base: reinstall it (sudo apt install --reinstall ros-noetic-move-base)")


def test_closing_while_starting_stops_the_start(stack_env):
    stack = make_stack(stack_env)
    errors = []

    def start():
        try:
            stack.start("navigation", os.path.join(ROOT, "config", "maps", "demo.yaml"))
        except StackFailed as exc:
            errors.append(str(exc))

    starter = threading.Thread(target=start)
    starter.start()
    wait_for(lambda: any("stub_packages" in c for c in stack_processes(stack_env["ROS_MASTER_URI"]).values()),
             timeout=20, message="roslaunch to start its nodes")
    stack.close()
    starter.join(30)
    assert errors == ["the navigation stack was stopped before it was ready"]
    assert nothing_left(stack_env["ROS_MASTER_URI"])


def test_a_stack_left_by_a_dead_server_is_stopped_by_the_next_one():
    from flask_move_server.process import children

    gone = subprocess.Popen(["true"])
    gone.wait()  # a server pid that no longer exists
    orphan = subprocess.Popen(["sleep", "600"], env=dict(os.environ, **{children.MARKER: "{}:1".format(gone.pid)}),
                              preexec_fn=default_sigint)  # SIGINT ends it, even when this pytest ignores SIGINT
    ours = subprocess.Popen(["sleep", "600"], env=dict(os.environ, **{children.MARKER: "{}:999".format(os.getpid())}),
                            preexec_fn=default_sigint)
    try:
        LaunchedStack(ModesConfig()).start("idle")
        assert orphan.wait(5) == -signal.SIGINT
        assert ours.poll() is None  # a live server's stack is its own business
    finally:
        for proc in (orphan, ours):
            if proc.poll() is None:
                proc.kill()
                proc.wait()


@pytest.mark.parametrize("line,level", [
    ("[ERROR] [1700000000.1]: Failed to load map", "ERROR"),
    ("[ WARN] [1700000000.123456]: Timed out waiting for transform", "WARNING"),
    ("[move_base-5] process has died [pid 12, exit code 1, cmd x __log:=/l/move_base-5.log].", "ERROR"),
    ("process[amcl-4]: started with pid [4242]", "INFO"),
    ("update frame 12", "DEBUG"),  # gmapping's chatter, several lines per scan: kept out of the journal
    ("Average Scan Matching Score=301.2", "DEBUG"),
])
def test_the_stacks_output_reaches_the_journal_at_its_level(line, level):
    import logging

    assert logging.getLevelName(child.level_of(line)) == level


def test_every_node_of_the_stack_is_told_to_write_line_by_line():
    """roslaunch's nodes write into the server's pipe: roscpp's stdout is then fully buffered (INFO
    lines minutes late, spliced into WARN lines) unless rosconsole is told ROSCONSOLE_STDOUT_LINE_BUFFERED
    (rosconsole 1.13.1 on), and rospy's unless PYTHONUNBUFFERED: the whole tree gets both."""
    proc = child.StackProcess(["sh", "-c", "echo rosconsole=$ROSCONSOLE_STDOUT_LINE_BUFFERED python=$PYTHONUNBUFFERED"])
    proc.start()
    wait_for(lambda: proc.exit_code() is not None and proc.last_lines(), timeout=10, message="the line")
    assert "rosconsole=1 python=1" in proc.last_lines()
