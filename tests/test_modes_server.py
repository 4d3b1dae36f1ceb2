"""The modes as ``cli`` wires them, in a real server process on the test session's ROS master."""

from geometry_msgs.msg import PoseWithCovarianceStamped

from tests.conftest import ServerProcess, wait_for
from tests.robot_fixtures import SEED, Recorder


def test_a_server_whose_stack_runs_elsewhere_reports_it_and_still_sets_the_pose(
        tmp_path, ros_master, ros_node, unique_name):
    (tmp_path / "waypoints.yaml").write_text(SEED)
    config = tmp_path / "robot.yaml"
    config.write_text("ros:\n  node_name: {0}_server\n  frames:\n    map: {0}_map\n"
                      "modes:\n  stack: none\n  initial_pose_topic: /{0}/initialpose\n".format(unique_name))
    recorder = Recorder("/{}/initialpose".format(unique_name), PoseWithCovarianceStamped)
    server = ServerProcess("--config", str(config), "--host", "127.0.0.1", "--port", "0", "--no-mdns",
                           "--waypoints", str(tmp_path / "waypoints.yaml"), "--motor-backend", "none")
    try:
        wait_for(lambda: server.get("/health").json()["ros"] == "connected", 30, message="the server's node")
        mode = server.get("/mode").json()
        assert (mode["mode"], mode["map"], mode["state"]) == ("navigation", None, "running")
        assert server.get("/status").json()["mode"] == mode
        r = server.post("/mode", {"mode": "mapping"})
        assert r.status_code == 409 and r.json()["error"] == "modes_off"
        r = server.post("/pose", {"name": "office"})
        assert r.status_code == 200, r.text
        wait_for(recorder.snapshot, 10, message="the estimate on /initialpose")
        msg = recorder.snapshot()[0][1]
        assert msg.header.frame_id == unique_name + "_map"
        assert (msg.pose.pose.position.x, msg.pose.pose.position.y) == (5.67, 2.34)
        assert server.stop() == 0
    finally:
        server.kill()
        recorder.close()
    assert not (tmp_path / "mode.json").exists()  # nothing switched, nothing remembered
