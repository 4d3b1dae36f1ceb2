"""The HTTP API against the real robot: rospy, actionlib, tf2, a scripted move_base."""

import http.client
import json
import math
import time

import pytest
import requests

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
    assert "aborted" in body["message"]
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


def test_topic_interface_publishes_move_base_simple_goal(ros_node, robot_config, tmp_path):
    from geometry_msgs.msg import PoseStamped

    from flask_move_server import cli
    from flask_move_server.waypoints import WaypointStore
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


def test_waypoints_list_get_put_delete(client, robot_config):
    path = robot_config.waypoints.file
    assert [w["name"] for w in client.get("/waypoints").get_json()["waypoints"]] == ["kitchen", "office", "dock"]
    assert client.get("/waypoints/office").get_json() == {"name": "office", "x": 5.67, "y": 2.34, "yaw": -1.57}
    r = client.put("/waypoints/living room", json={"x": 1, "y": 2, "yaw": 0.5})
    assert r.status_code == 201 and r.get_json()["created"] is True
    assert '"living room": [1.0, 2.0, 0.5]' in open(path).read()  # saved before the response
    r = client.put("/waypoints/living room", json={"x": 3, "y": 2, "yaw": 0.5})
    assert r.status_code == 200 and r.get_json()["created"] is False
    assert client.delete("/waypoints/office").status_code == 204
    assert "office" not in open(path).read()
    assert client.get("/waypoints/office").status_code == 404


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


# -- bad input: always a 4xx JSON error, never a 500 or HTML, the file untouched ---------------

BAD = [
    ("post", "/goto", b"{not json", 400),
    ("post", "/goto", b"", 400),
    ("post", "/goto", b"[1, 2]", 400),
    ("post", "/goto", b'"kitchen"', 400),
    ("post", "/goto", b'{"name": 5}', 400),
    ("post", "/goto", b'{"name": null}', 400),
    ("post", "/goto", b'{"x": NaN, "y": 0}', 400),
    ("post", "/goto", b'{"x": Infinity, "y": 0}', 400),
    ("post", "/goto", b'{"x": 1e999, "y": 0}', 400),
    ("post", "/goto", b'{"x": "1", "y": 0}', 400),
    ("post", "/goto", b'{"x": true, "y": 0}', 400),
    ("post", "/goto", b'{"x": 1}', 400),
    ("post", "/goto", b'{"name": "kitchen", "x": 1}', 400),
    ("post", "/goto", b'{"nmae": "kitchen"}', 400),
    ("post", "/goto", b'{"name": "kitchen", "wait": -1}', 400),
    ("post", "/goto", b'{"name": "a/b"}', 400),
    ("post", "/goto", b'{"name": ".."}', 400),
    ("post", "/goto", b'{"name": "bell\\u0007"}', 400),
    ("post", "/goto", ('{"name": "%s"}' % ("x" * 300)).encode(), 400),
    ("post", "/goto", b"\xff\xfe", 400),
    ("post", "/goto", b"[" * 5000 + b"]" * 5000, 400),
    ("post", "/goto", b'{"a":' * 2000 + b"1" + b"}" * 2000, 400),
    ("post", "/goto", b'{"name": "' + b"x" * 20000 + b'"}', 413),
    ("post", "/goto", b'{"x": 1e308, "y": 0}', 400),
    ("post", "/goto", b'{"x": 0, "y": -1000001}', 400),
    ("post", "/goto", b'{"x": 0, "y": 0, "yaw": 1e300}', 400),
    ("post", "/goto", b'{"x": 1' + b"0" * 400 + b', "y": 0}', 400),
    ("post", "/goto", b'{"name": "dock", "name": "kitchen"}', 400),
    ("post", "/teleop", b'{"linear": "fast"}', 400),
    ("post", "/teleop", b'{"linear": 0.1, "linear": 5}', 400),
    ("post", "/teleop", b'{"linear": NaN}', 400),
    ("post", "/teleop", b'{"speed": 1}', 400),
    ("post", "/stop", b"{oops", 400),
    ("put", "/waypoints/ok", b'{"x": 1, "y": 2}', 400),
    ("put", "/waypoints/ok", b'{"x": 1, "y": 2, "yaw": NaN}', 400),
    ("put", "/waypoints/ok", b'{"x": 1, "y": 2, "yaw": -Infinity}', 400),
    ("put", "/waypoints/ok", b'{"x": [1], "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/ok", b'{"x": 1e308, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/ok", b'{"x": 1, "y": 2, "yaw": -1001}', 400),
    ("put", "/waypoints/ok", b'{"x": 1, "y": 2, "yaw": 0, "x": 5}', 400),
    ("put", "/waypoints/ok", b'{"from": "yesterday"}', 400),
    ("put", "/waypoints/ok", b'{"from": "current", "x": 1}', 400),
    ("put", "/waypoints/a%2Fb", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/a/b", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/..", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/a..b", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/tab%09", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/nul%00", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/new%0Aline", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/.", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("get", "/waypoints/new%0Aline", None, 400),
    ("delete", "/waypoints/line%0A", None, 400),
    ("put", "/waypoints/" + "x" * 300, b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/%20lead", b'{"x": 1, "y": 2, "yaw": 0}', 400),
    ("put", "/waypoints/ok", b"[" * 5000 + b"]" * 5000, 400),
    ("delete", "/waypoints/nope", None, 404),
    ("delete", "/waypoints/a%2F..%2Fb", None, 400),
    ("get", "/waypoints/" + "y" * 65, None, 400),
    ("get", "/goto", None, 405),
    ("delete", "/status", None, 405),
    ("get", "/no/such/endpoint", None, 404),
]


def _case_id(case):
    method, path, body, status = case
    shown = (body or b"")[:24].decode("utf-8", "replace")
    return "{} {} {}{} -> {}".format(method, path[:30], shown, "..." if body and len(body) > 24 else "", status)


@pytest.mark.parametrize("method,path,body,status", BAD, ids=[_case_id(c) for c in BAD])
def test_bad_input_is_a_json_4xx_and_changes_nothing(client, robot_config, method, path, body, status):
    r = getattr(client, method)(path, data=body, content_type="application/json")
    assert r.status_code == status, r.get_data(as_text=True)[:300]
    assert r.is_json, r.get_data(as_text=True)[:300]
    err = r.get_json()
    assert err["status"] == "error" and err["error"] and len(err["message"]) > 10
    assert open(robot_config.waypoints.file).read() == SEED
    assert client.get("/status").get_json()["navigation"]["state"] == "idle"


def test_a_control_character_in_a_url_name_is_a_bad_name_not_a_missing_endpoint(client):
    r = client.put("/waypoints/kitchen%0Adoor", json={"x": 1, "y": 2, "yaw": 0})
    assert r.status_code == 400 and r.get_json()["error"] == "bad_waypoint"
    assert "kitchen\\ndoor" in r.get_json()["message"] and "letters, digits" in r.get_json()["message"]


def test_dot_is_not_a_name_a_client_could_delete(client):
    r = client.put("/waypoints/.", json={"x": 1, "y": 2, "yaw": 0})
    assert r.status_code == 400 and "not '.' alone" in r.get_json()["message"]
    assert client.post("/goto", json={"name": "."}).status_code == 400


def test_a_field_given_twice_is_refused_naming_it(client):
    r = client.put("/waypoints/ok", data=b'{"x": 1, "y": 2, "yaw": 0, "y": 2000}')
    assert r.status_code == 400 and r.get_json()["error"] == "bad_request"
    assert r.get_json()["message"] == 'The field "y" appears twice in the body; send each field once.'


def test_coordinates_beyond_the_bound_are_refused_saying_the_bound(client):
    r = client.post("/goto", json={"x": 1e308, "y": 0})
    assert r.status_code == 400
    assert r.get_json()["message"] == "x must be between -1000000 and 1000000, got 1e+308."
    r = client.put("/waypoints/far", json={"x": 0, "y": 0, "yaw": 5000})
    assert r.status_code == 400 and "between -1000 and 1000" in r.get_json()["message"]
    r = client.put("/waypoints/edge", json={"x": 1e6, "y": -1e6, "yaw": -1000})
    assert r.status_code == 201


def test_a_wrong_method_names_the_right_one(client):
    r = client.get("/goto")
    assert r.status_code == 405 and r.get_json()["message"] == "/goto takes POST, not GET."
    assert "POST" in r.headers["Allow"]


def test_any_content_type_is_read_as_json(client, ready_robot):
    for ctype in (None, "application/x-www-form-urlencoded", "text/plain"):
        r = client.post("/goto", data='{"name":"dock"}', content_type=ctype)
        assert r.status_code == 202, ctype


# -- auth --------------------------------------------------------------------------------------

ROUTES = [
    ("post", "/goto", {"name": "dock"}),
    ("post", "/stop", None),
    ("post", "/teleop", {"linear": 0.1}),
    ("get", "/waypoints", None),
    ("get", "/waypoints/dock", None),
    ("put", "/waypoints/new", {"x": 1, "y": 1, "yaw": 0}),
    ("delete", "/waypoints/dock", None),
    ("get", "/status", None),
]


@pytest.fixture
def token_client(robot_config, robot, store):
    from flask_move_server.web import create_app

    return create_app(robot_config, robot, store, token="s3cret").test_client()


@pytest.mark.parametrize("method,path,body", ROUTES)
def test_every_route_needs_the_token(token_client, robot_config, method, path, body):
    for headers in ({}, {"Authorization": "Bearer wrong"}, {"Authorization": "s3cret"},
                    {"Authorization": "Basic czNjcmV0"}):
        r = getattr(token_client, method)(path, json=body, headers=headers)
        assert r.status_code == 401 and r.get_json()["error"] == "unauthorized"
        assert r.headers["WWW-Authenticate"].startswith("Bearer")
    assert open(robot_config.waypoints.file).read() == SEED
    r = getattr(token_client, method)(path, json=body, headers={"Authorization": "Bearer s3cret"})
    assert r.status_code != 401


def test_health_and_the_page_need_no_token(token_client):
    assert token_client.get("/health").status_code == 200
    assert token_client.get("/").status_code == 200


def test_a_configured_token_with_a_trailing_newline_is_the_token_over_http(robot_config, robot, store):
    from flask_move_server.web import create_app

    robot_config.server.token = "s3cret\n"  # as pasted from a file: the newline is not the secret
    app = create_app(robot_config, robot, store, token=robot_config.resolved_token())
    with serve(app) as url:
        assert requests.get(url + "/waypoints", headers={"Authorization": "Bearer s3cret"}, timeout=10).ok
        r = requests.get(url + "/waypoints", headers={"Authorization": "Bearer s3cre"}, timeout=10)
        assert r.status_code == 401


# -- through a real waitress server --------------------------------------------------------------


def test_over_real_http(app, ready_robot, move_base):
    with serve(app) as url:
        r = requests.post(url + "/goto", data='{"name": "kitchen", "wait": 30}', timeout=35)
        assert r.status_code == 200 and r.json()["navigation"]["state"] == "succeeded"
        r = requests.post(url + "/goto", data=b"x" * 100000, timeout=10)
        assert r.status_code == 413 and r.json()["error"] == "body_too_large"
        r = requests.get(url + "/nothing", timeout=10)
        assert r.status_code == 404 and r.headers["Content-Type"] == "application/json"
        assert json.loads(r.text)["status"] == "error"
        assert requests.get(url + "/health", timeout=10).json()["move_base"] == "ready"


def test_empty_answers_carry_no_html_type(app):
    with serve(app) as url:
        for method, path in (("OPTIONS", "/goto"), ("OPTIONS", "/waypoints/dock"), ("DELETE", "/waypoints/dock")):
            conn = http.client.HTTPConnection(url[len("http://"):], timeout=10)
            conn.request(method, path)
            r = conn.getresponse()
            assert r.status in (200, 204) and r.read() == b""
            assert r.getheader("Content-Type") is None, (method, path, r.getheaders())
            conn.close()
