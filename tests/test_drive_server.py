"""The whole server process with ``--motor-backend sim``: teleop turns the motors, silence stops them."""

import re
import threading

import pytest
import requests

from tests.conftest import free_port, run_cli, start_master, stop_process, wait_for


class Server:
    """``flask-move-server`` as a child process on its own master."""

    def __init__(self, tmp_path, master_uri, *extra):
        env = {"ROS_MASTER_URI": master_uri, "ROS_HOME": str(tmp_path), "ROS_IP": "127.0.0.1"}
        self.proc = run_cli("--host", "127.0.0.1", "--port", "0", "--no-mdns", "--motor-backend", "sim",
                            "--waypoints", str(tmp_path / "waypoints.yaml"), *extra, env=env)
        self.lines = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.url = wait_for(lambda: self._find(r"serving the API on (http://\S+)"), timeout=30,
                            message="the server's URL").group(1)
        wait_for(lambda: self.get("/health").json()["ros"] == "connected", timeout=30, interval=0.2,
                 message="the server to connect to ROS")

    def _read(self):
        for line in self.proc.stderr:
            self.lines.append(line)

    def _find(self, pattern):
        return next((m for m in (re.search(pattern, line) for line in list(self.lines)) if m), None)

    def get(self, path):
        return requests.get(self.url + path, timeout=10)

    def motors(self):
        return self.get("/status").json()["motors"]


@pytest.fixture
def master():
    port = free_port()
    proc = start_master(port)
    yield proc, "http://127.0.0.1:{}".format(port)
    stop_process(proc)


@pytest.fixture
def servers():
    started = []
    yield started
    for server in started:
        stop_process(server.proc)
        server._reader.join(5)


def test_teleop_turns_the_sim_motors_and_they_stop_after_the_deadman(tmp_path, master, servers):
    servers.append(Server(tmp_path, master[1]))
    server = servers[0]
    assert server.motors()["backend"] == "sim" and server.motors()["left"] == 0.0
    r = requests.post(server.url + "/teleop", json={"linear": 0.2, "angular": 0.0}, timeout=10)
    assert r.status_code == 200
    moving = wait_for(lambda: server.motors()["left"] > 0 and server.motors(), message="the motors to turn")
    assert moving["right"] > 0
    stopped = wait_for(lambda: server.motors()["left"] == 0.0 and server.motors(), message="the motors to stop")
    assert stopped["right"] == 0.0
    odom = server.get("/status").json()["motors"]["odom"]
    assert odom["x"] > 0 and odom["source"] == "open_loop"
    server.proc.terminate()
    assert server.proc.wait(15) == 0


def test_losing_the_master_stops_the_motors(tmp_path, master, servers):
    config = tmp_path / "robot.yaml"
    config.write_text("ros:\n  master_check_period: 0.2\n  exit_on_new_master: false\n"
                      "teleop:\n  deadman: 60\ndrive:\n  cmd_vel_timeout: 60\n")
    servers.append(Server(tmp_path, master[1], "--config", str(config)))
    server = servers[0]
    requests.post(server.url + "/teleop", json={"linear": 0.2}, timeout=10)
    wait_for(lambda: server.motors()["left"] > 0, message="the motors to turn")
    stop_process(master[0])
    stopped = wait_for(lambda: server.motors()["left"] == 0.0 and server.motors(), message="the motors to stop")
    assert stopped["watchdog_tripped"] is True and stopped["right"] == 0.0
    assert server.get("/health").json()["ros"] == "lost"


def test_the_base_controller_runs_alone_for_mapping(ros_node, ros_master, unique_name):
    import subprocess
    import sys

    import rospy
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry

    from tests.conftest import ROOT

    odom_topic, cmd_topic = "/{}/odom".format(unique_name), "/{}/cmd_vel".format(unique_name)
    proc = subprocess.Popen(
        [sys.executable, "-m", "flask_move_server.drive", "--motor-backend", "sim",
         "__name:=" + unique_name + "_base", "cmd_vel:=" + cmd_topic, "odom:=" + odom_topic],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    odoms = []
    sub = rospy.Subscriber(odom_topic, Odometry, odoms.append)
    pub = rospy.Publisher(cmd_topic, Twist, queue_size=1)
    try:
        wait_for(lambda: odoms and pub.get_num_connections() > 0, timeout=30, message="the base node")
        msg = Twist()
        msg.linear.x = 0.3
        wait_for(lambda: (pub.publish(msg) or True) and odoms[-1].pose.pose.position.x > 0.02,
                 timeout=15, interval=0.1, message="the robot to move in odometry")
        proc.terminate()
        assert proc.wait(15) == 0
    finally:
        sub.unregister()
        pub.unregister()
        stop_process(proc)


def test_the_base_controller_alone_refuses_backend_none():
    import subprocess
    import sys

    from tests.conftest import ROOT

    result = subprocess.run([sys.executable, "-m", "flask_move_server.drive"], cwd=ROOT,
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "drive.backend" in result.stderr and "--motor-backend" in result.stderr
