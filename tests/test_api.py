"""The HTTP API against the real robot: rospy, actionlib, tf2, a scripted move_base.

What ROS does with each request: goals reaching move_base, velocities on /cmd_vel, poses from tf
and AMCL. Validation, auth and error shapes, which ROS plays no part in, are tests/test_web.py's.
"""

import json
import math
import threading
import time

import pytest
import requests

from flask_move_server.core.errors import NavigationFailed
from tests.conftest import serve, wait_for
from tests.robot_fixtures import SEED, Recorder, publish_pose
from tests.standins.move_base import ABORT_X, HOLD_X


def _goal_xy(move_base, index=-1):
    p = move_base.goals[index][1].target_pose
    return p.header.frame_id, p.pose.position.x, p.pose.position.y


# -- goals -------------------------------------------------------------------------------------


def test_goto_a_name_sends_its_pose_to_move_base(client, ready_robot, move_base, robot_config):
    r = client.post("/goto", data='{"name": "kitchen"}')
    assert r.status_code == 202
    assert r.get_json() == {"status": "ok", "target": "kitchen", "goal": {"x": 1.23, "y": 4.56, "yaw": 0.79},
                            "goal_id": r.get_json()["goal_id"]}
    wait_for(lambda: move_base.goals, message="move_base to receive the goal")
    assert _goal_xy(move_base) == (robot_config.ros.frames.map, 1.23, 4.56)
    q = move_base.goals[-1][1].target_pose.pose.orientation
    assert math.isclose(2 * math.atan2(q.z, q.w), 0.79, abs_tol=1e-9)


def test_goto_coordinates(client, ready_robot, move_base):
    r = client.post("/goto", json={"x": 2.0, "y": -1.5})
    assert r.status_code == 202 and r.get_json()["target"] is None
    assert r.get_json()["goal"] == {"x": 2.0, "y": -1.5, "yaw": 0.0}
    wait_for(lambda: move_base.goals)
    assert _goal_xy(move_base)[1:] == (2.0, -1.5)


def test_goto_with_wait_answers_200_when_reached(client, ready_robot):
    r = client.post("/goto", json={"name": "office", "wait": 30})
    assert r.status_code == 200
    assert r.get_json()["navigation"]["state"] == "succeeded"
    assert client.get("/status").get_json()["navigation"]["state"] == "succeeded"


def test_an_aborted_goal_is_reported(client, ready_robot):
    r = client.post("/goto", json={"x": ABORT_X, "y": 0, "wait": 30})
    assert r.status_code == 409
    body = r.get_json()
    assert body["status"] == "error" and body["error"] == "navigation_failed" and body["state"] == "aborted"
    # move_base's own reason replaces the guess; a goal to x, y: no waypoint name to quote
    assert body["message"] == "move_base aborted the goal: no path."
    assert client.get("/status").get_json()["navigation"]["state"] == "aborted"


def test_wait_that_runs_out_answers_202_still_active(client, ready_robot):
    r = client.post("/goto", json={"x": HOLD_X, "y": 0, "wait": 0.3})
    assert r.status_code == 202 and r.get_json()["navigation"]["state"] == "active"
    client.post("/stop")


def test_stop_cancels_the_goal(client, ready_robot, move_base):
    client.post("/goto", json={"x": HOLD_X, "y": 0})
    wait_for(lambda: move_base.goals, message="the goal to reach move_base")
    r = client.post("/stop")
    assert r.status_code == 200 and r.get_json()["canceled_goal"] is True
    wait_for(lambda: client.get("/status").get_json()["navigation"]["state"] == "canceled",
             message="the goal to end canceled")


def test_a_new_goal_replaces_the_old_and_late_news_of_the_old_is_ignored(client, ready_robot, move_base):
    first = client.post("/goto", json={"x": HOLD_X, "y": 0}).get_json()["goal_id"]
    wait_for(lambda: move_base.goals)
    second = client.post("/goto", json={"name": "dock", "wait": 30})
    assert second.status_code == 200
    nav = client.get("/status").get_json()["navigation"]
    assert nav["state"] == "succeeded" and nav["target"] == "dock" and nav["goal_id"] == first + 1


def test_a_waiting_goto_replaced_by_a_newer_goal_names_its_own_place(client, ready_robot, move_base):
    assert client.put("/waypoints/far hall", json={"x": HOLD_X, "y": 0, "yaw": 0}).status_code == 201
    answers = []
    waiting = threading.Thread(target=lambda: answers.append(client.post("/goto", json={"name": "far hall",
                                                                                          "wait": 30})))
    waiting.start()
    wait_for(lambda: move_base.goals, message="the goal to the far hall to reach move_base")
    assert client.post("/goto", json={"name": "dock"}).status_code == 202
    waiting.join(10)
    body = answers[0].get_json()
    assert answers[0].status_code == 409 and body["error"] == "navigation_failed" and body["state"] == "canceled"
    assert body["message"] == "The goal to 'far hall' was replaced by a newer goal."


def test_a_goal_that_ended_before_a_newer_one_came_answers_its_own_end(client, ready_robot, move_base):
    arrived = client.post("/goto", json={"name": "office"}).get_json()["goal_id"]
    wait_for(lambda: client.get("/status").get_json()["navigation"]["state"] == "succeeded",
             message="the goal to the office to succeed")
    held = client.post("/goto", json={"x": HOLD_X, "y": 0}).get_json()["goal_id"]  # before a waiter woke
    assert ready_robot.wait(arrived, 0) is True  # arrived: not "replaced"
    client.post("/stop")
    wait_for(lambda: client.get("/status").get_json()["navigation"]["state"] == "canceled")
    client.post("/goto", json={"name": "dock"})
    with pytest.raises(NavigationFailed) as failed:  # stopped, then replaced: canceled by /stop
        ready_robot.wait(held, 0)
    assert failed.value.state == "canceled"
    assert str(failed.value) == "The goal was canceled before the robot arrived."


def test_goto_an_unknown_name_is_404_with_close_names(client, ready_robot, move_base):
    r = client.post("/goto", json={"name": "kitchn"})
    assert r.status_code == 404
    assert r.get_json()["suggestions"] == ["kitchen"]
    assert "kitchen" in r.get_json()["message"]
    assert not move_base.goals


def test_goto_without_move_base_is_503_naming_the_action(client, robot):
    r = client.post("/goto", json={"name": "kitchen"})
    assert r.status_code == 503
    assert r.get_json()["error"] == "move_base_unavailable"
    assert "/move_base" in r.get_json()["message"] and "navigation" in r.get_json()["message"]
    assert client.get("/health").get_json() == {"status": "ok", "ros": "connected", "move_base": "unavailable"}


def test_goto_after_move_base_went_away_is_503_again(client, ready_robot, move_base):
    """A move_base found ready is remembered only while its connections stay: when it goes, goals are refused."""
    assert client.post("/goto", json={"x": 1.0, "y": 0.0}).status_code == 202
    assert client.post("/goto", json={"x": 2.0, "y": 0.0}).status_code == 202
    move_base.shutdown()
    wait_for(lambda: client.post("/goto", json={"x": 3.0, "y": 0.0}).status_code == 503, timeout=15,
             message="/goto to answer 503 once move_base is gone")
    r = client.post("/goto", json={"x": 4.0, "y": 0.0})
    assert r.status_code == 503 and r.get_json()["error"] == "move_base_unavailable"
    assert client.get("/health").get_json()["move_base"] == "unavailable"


def test_topic_interface_publishes_move_base_simple_goal(ros_node, robot_config, tmp_path):
    from geometry_msgs.msg import PoseStamped

    from flask_move_server.app import cli
    from flask_move_server.waypoints.store import WaypointStore
    from flask_move_server.web import create_app
    from tests.robot_fixtures import no_drive

    robot_config.navigation.goal_interface = "topic"
    heard = Recorder(robot_config.navigation.simple_goal_topic, PoseStamped)
    robot = cli.build_robot(robot_config, ros_node, no_drive())
    try:
        test_client = create_app(robot_config, robot, WaypointStore(robot_config.waypoints.file)).test_client()
        wait_for(lambda: robot.navigator._goal_pub.get_num_connections(), message="the goal topic to connect")
        assert test_client.post("/goto", json={"name": "office"}).status_code == 202
        wait_for(lambda: heard.snapshot(), message="a PoseStamped on move_base_simple/goal")
        msg = heard.snapshot()[-1][1]
        assert (msg.header.frame_id, msg.pose.position.x, msg.pose.position.y) == (
            robot_config.ros.frames.map, 5.67, 2.34)
        assert test_client.post("/stop").get_json()["canceled_goal"] is True
    finally:
        heard.close()
        robot.close()


# -- status, pose ------------------------------------------------------------------------------


def test_status_shows_pose_from_tf_and_distance_remaining(client, ready_robot, robot_config):
    wait_for(lambda: publish_pose(robot_config, 1.0, 1.0, 0.5) or client.get("/status").get_json()["pose"],
             message="the pose from tf")
    client.post("/goto", json={"x": HOLD_X, "y": 1.0})
    status = client.get("/status").get_json()
    assert status["pose"]["frame"] == robot_config.ros.frames.map
    assert math.isclose(status["pose"]["x"], 1.0) and math.isclose(status["pose"]["yaw"], 0.5)
    assert status["pose"]["age"] >= 0
    assert math.isclose(status["navigation"]["distance_remaining"], abs(HOLD_X - 1.0), abs_tol=0.01)
    assert (status["motors"]["backend"], status["motors"]["left"], status["motors"]["right"]) == ("none", 0.0, 0.0)
    assert status["ros"]["state"] == "connected"
    client.post("/stop")


def test_pose_falls_back_to_amcl_pose(client, robot, robot_config):
    import rospy
    from geometry_msgs.msg import PoseWithCovarianceStamped

    pub = rospy.Publisher(robot_config.navigation.amcl_pose_topic, PoseWithCovarianceStamped, queue_size=1, latch=True)
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = robot_config.ros.frames.map
    msg.header.stamp = rospy.Time.now()
    msg.pose.pose.position.x, msg.pose.pose.orientation.w = 3.5, 1.0
    pub.publish(msg)
    pose = wait_for(lambda: client.get("/status").get_json()["pose"], message="the AMCL pose")
    assert pose["x"] == 3.5 and pose["source"] == "amcl_pose"
    pub.unregister()


# -- teleop ------------------------------------------------------------------------------------


def test_a_goal_ends_teleop_with_a_zero_twist_and_leaves_cmd_vel_alone_when_nobody_drives(
        client, ready_robot, move_base, robot_config):
    from geometry_msgs.msg import Twist

    heard = Recorder(robot_config.teleop.topic, Twist)
    try:
        wait_for(lambda: ready_robot.teleop_control._pub.get_num_connections(), message="cmd_vel to connect")
        assert client.post("/goto", json={"x": HOLD_X, "y": 0}).status_code == 202
        time.sleep(0.3)  # a Twist, had one been sent, has arrived by now
        assert heard.snapshot() == [], "no zero Twist for a base nobody drives"
        assert client.post("/teleop", json={"linear": 0.2}).status_code == 200
        wait_for(lambda: heard.snapshot(), message="the teleop Twist")
        assert client.post("/goto", json={"x": HOLD_X, "y": 0}).status_code == 202
        assert client.get("/status").get_json()["teleop"]["active"] is False
        wait_for(lambda: heard.snapshot()[-1][1].linear.x == 0, timeout=5, message="the zero Twist ending teleop")
    finally:
        heard.close()


def test_teleop_publishes_clamped_velocity_held_then_zero(client, robot, robot_config):
    from geometry_msgs.msg import Twist

    heard = Recorder(robot_config.teleop.topic, Twist)
    try:
        wait_for(lambda: robot.teleop_control._pub.get_num_connections(), message="cmd_vel to connect")
        r = client.post("/teleop", json={"linear": 5.0, "angular": -0.3})
        assert r.status_code == 200
        assert r.get_json() == {"status": "ok", "linear": 0.4, "angular": -0.3, "hold": 0.5}
        wait_for(lambda: any(m.linear.x == 0 for _, m in heard.snapshot()[1:]), timeout=5,
                 message="the zero Twist after the deadman")
        msgs = heard.snapshot()
        moving = [m for _, m in msgs if m.linear.x != 0]
        assert moving and all(m.linear.x == 0.4 and m.angular.z == -0.3 for m in moving)
        assert len(moving) >= 3, "the command is re-published while it holds"
        assert msgs[-1][1].linear.x == 0 and msgs[-1][1].angular.z == 0
        held = msgs[-1][0] - msgs[0][0]
        assert 0.4 <= held, "the command held for the deadman time"
        assert client.get("/status").get_json()["teleop"]["active"] is False
    finally:
        heard.close()


def test_teleop_cancels_an_active_goal(client, ready_robot, move_base):
    client.post("/goto", json={"x": HOLD_X, "y": 0})
    wait_for(lambda: move_base.goals)
    r = client.post("/teleop", json={"linear": 0.1, "angular": 0})
    assert r.get_json()["canceled_goal"] is True
    wait_for(lambda: client.get("/status").get_json()["navigation"]["state"] == "canceled")


# -- waypoints ---------------------------------------------------------------------------------


def test_put_from_current_records_the_pose_now(client, robot, robot_config):
    wait_for(lambda: publish_pose(robot_config, -2.0, 0.25, -1.0) or robot.pose.current(), message="tf pose")
    r = client.put("/waypoints/here", json={"from": "current"})
    assert r.status_code == 201
    wp = r.get_json()["waypoint"]
    assert (wp["x"], wp["y"]) == (-2.0, 0.25) and math.isclose(wp["yaw"], -1.0)


def test_put_from_current_refuses_a_stale_pose(client, robot, robot_config):
    import rospy
    from geometry_msgs.msg import PoseWithCovarianceStamped

    pub = rospy.Publisher(robot_config.navigation.amcl_pose_topic, PoseWithCovarianceStamped, queue_size=1, latch=True)
    msg = PoseWithCovarianceStamped()
    msg.header.frame_id = robot_config.ros.frames.map
    msg.header.stamp = rospy.Time.now() - rospy.Duration(10.0)  # localization stopped 10 s ago
    msg.pose.pose.position.x, msg.pose.pose.orientation.w = 3.5, 1.0
    pub.publish(msg)
    try:
        wait_for(lambda: robot.pose.current(), message="the AMCL pose")
        r = client.put("/waypoints/here", json={"from": "current"})
        assert r.status_code == 409 and r.get_json()["error"] == "no_pose"
        assert "s old" in r.get_json()["message"] and "pose_max_age" in r.get_json()["message"]
        assert open(robot_config.waypoints.file).read() == SEED
        assert client.get("/status").get_json()["pose"]["age"] >= 10  # still shown, with its age
    finally:
        pub.unregister()


def test_put_from_current_without_a_pose_is_409(client, robot_config):
    r = client.put("/waypoints/here", json={"from": "current"})
    assert r.status_code == 409 and r.get_json()["error"] == "no_pose"
    assert open(robot_config.waypoints.file).read() == SEED


# -- through a real waitress server --------------------------------------------------------------


def test_over_real_http(app, ready_robot, move_base):
    with serve(app) as url:
        r = requests.post(url + "/goto", data='{"name": "kitchen", "wait": 30}', timeout=35)
        assert r.status_code == 200 and r.json()["navigation"]["state"] == "succeeded"
        r = requests.post(url + "/goto", data=b"x" * 100000, timeout=10)
        assert r.status_code == 413 and r.json()["error"] == "body_too_large"
        r = requests.get(url + "/nothing", timeout=10)
        assert r.status_code == 404 and r.headers["Content-Type"] == "application/json; charset=utf-8"
        assert json.loads(r.text)["status"] == "error"
        assert requests.get(url + "/health", timeout=10).json()["move_base"] == "ready"
