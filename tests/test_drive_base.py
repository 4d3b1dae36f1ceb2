"""The base controller with a real ROS master: /cmd_vel in, motors, watchdog, /odom and tf out."""

import math

import pytest

from flask_move_server.config import DriveConfig, FramesConfig
from flask_move_server.core.errors import ConfigError
from flask_move_server.drive import NoDrive, make_drive
from flask_move_server.drive.backends.sim import SimBackend
from tests.conftest import wait_for


@pytest.fixture
def topics(unique_name):
    config = DriveConfig(backend="sim", cmd_vel_topic=unique_name + "/cmd_vel", odom_topic=unique_name + "/odom")
    frames = FramesConfig(odom=unique_name + "_odom", base_link=unique_name + "_base_link")
    return config, frames


@pytest.fixture
def base(ros_node, topics):
    config, frames = topics
    controller = make_drive(config, ros_node, frames)
    yield controller
    controller.close()


def publisher(topic, controller=None):
    import rospy
    from geometry_msgs.msg import Twist

    pub = rospy.Publisher(topic, Twist, queue_size=1, tcp_nodelay=True)
    wait_for(lambda: pub.get_num_connections() > 0, message="the base controller to subscribe " + topic)
    return pub


def twist(linear=0.0, angular=0.0):
    from geometry_msgs.msg import Twist

    msg = Twist()
    msg.linear.x, msg.angular.z = linear, angular
    return msg


def test_one_cmd_vel_moves_the_motors_and_silence_stops_them_at_once(base, topics):
    config, _ = topics
    pub = publisher(config.cmd_vel_topic)
    pub.publish(twist(0.2, 0.0))
    moving = wait_for(lambda: base.status()["left"] > 0 and base.status(), message="the motors to turn")
    assert moving["right"] > 0 and moving["watchdog_tripped"] is False and moving["backend"] == "sim"
    stopped = wait_for(lambda: base.status()["watchdog_tripped"] and base.status(), message="the watchdog")
    assert stopped["left"] == 0.0 and stopped["right"] == 0.0
    assert stopped["command_age"] >= config.cmd_vel_timeout
    history = list(base.backend.history)
    last_moving = max(i for i, (_, left, _) in enumerate(history) if left != 0)
    silent_for = history[last_moving + 1][0] - (base.backend.history[0][0])
    assert silent_for >= config.cmd_vel_timeout * 0.9  # not before the timeout
    peak = max(left for _, left, _ in history)
    assert history[last_moving][1] == peak and history[last_moving + 1][1:] == (0.0, 0.0)  # a stop, not a ramp


def test_commands_keep_the_robot_moving_and_ramp_up(base, topics):
    config, _ = topics
    pub = publisher(config.cmd_vel_topic)
    pub.publish(twist(0.3, 0.0))
    first = wait_for(lambda: base.backend.history and base.backend.history[0], message="a motor command")
    assert 0 < first[1] < base.motion.motor.duty(0.3)  # the first step of the ramp, not the full speed
    full = base.motion.motor.duty(0.3)
    wait_for(lambda: (pub.publish(twist(0.3, 0.0)) or True) and math.isclose(base.status()["left"], full, rel_tol=1e-3),
             timeout=10, interval=0.1, message="the ramp to reach the commanded speed")
    assert base.status()["watchdog_tripped"] is False


def test_nan_and_inf_are_ignored_and_speeds_clamped(base, topics):
    config, _ = topics
    pub = publisher(config.cmd_vel_topic)
    pub.publish(twist(float("nan"), 0.0))
    pub.publish(twist(0.0, float("inf")))
    wait_for(lambda: base.status()["ignored_commands"] >= 1, message="the bad command to be counted")
    assert base.status()["left"] == 0.0 and base.status()["target"] == {"linear": 0.0, "angular": 0.0}
    pub.publish(twist(50.0, -50.0))
    status = wait_for(lambda: base.status()["target"]["linear"] and base.status(), message="the clamped command")
    assert status["target"] == {"linear": config.max_linear, "angular": -config.max_angular}


def test_turning_on_the_spot_drives_the_sides_apart(base, topics):
    config, _ = topics
    pub = publisher(config.cmd_vel_topic)
    pub.publish(twist(0.0, 1.0))  # counter-clockwise: left back, right forward
    status = wait_for(lambda: base.status()["right"] > 0 and base.status(), message="the turn")
    assert status["left"] < 0 and math.isclose(status["left"], -status["right"], rel_tol=1e-9)


def test_stop_halts_without_ramping(base, topics):
    assert base.command(0.3, 0.0)
    wait_for(lambda: base.status()["left"] > 0, message="the motors to turn")
    base.stop()
    assert base.status()["left"] == 0.0 and base.backend.applied()[:2] == (0.0, 0.0)


def test_odometry_and_tf_are_published_with_honest_covariance(base, topics):
    import rospy
    from nav_msgs.msg import Odometry
    from tf2_msgs.msg import TFMessage

    config, frames = topics
    odoms, transforms = [], []
    subs = [rospy.Subscriber(config.odom_topic, Odometry, odoms.append),
            rospy.Subscriber("/tf", TFMessage, lambda m: transforms.extend(
                t for t in m.transforms if t.child_frame_id == frames.base_link))]
    try:
        wait_for(lambda: odoms and transforms, message="odometry and tf")
        msg = odoms[-1]
        assert msg.header.frame_id == frames.odom and msg.child_frame_id == frames.base_link
        assert transforms[-1].header.frame_id == frames.odom
        assert msg.pose.covariance[0] > 0 and msg.pose.covariance[14] >= 1e5  # z is not observed
        start_var = msg.pose.covariance[0]
        for _ in range(20):
            base.command(0.3, 0.0)
            rospy.sleep(0.05)
        moved = wait_for(lambda: odoms[-1].pose.pose.position.x > 0.05 and odoms[-1], message="odometry to move")
        assert abs(moved.pose.pose.position.y) < 0.01 and moved.pose.covariance[0] > start_var
    finally:
        for sub in subs:
            sub.unregister()


def test_publish_tf_false_publishes_odometry_only(ros_node, topics):
    import rospy
    from nav_msgs.msg import Odometry
    from tf2_msgs.msg import TFMessage

    config, frames = topics
    config.publish_tf = False
    controller = make_drive(config, ros_node, frames)
    odoms, transforms = [], []
    subs = [rospy.Subscriber(config.odom_topic, Odometry, odoms.append),
            rospy.Subscriber("/tf", TFMessage, lambda m: transforms.extend(
                t for t in m.transforms if t.child_frame_id == frames.base_link))]
    try:
        wait_for(lambda: len(odoms) >= 10, message="ten odometry messages")
        assert transforms == []
    finally:
        controller.close()
        for sub in subs:
            sub.unregister()


def test_close_is_idempotent_and_stops_the_motors(ros_node, topics):
    config, frames = topics
    backend = SimBackend(config)
    controller = make_drive(config, ros_node, frames, backend=backend)
    controller.command(0.3, 0.0)
    wait_for(lambda: backend.applied()[0] > 0, message="the motors to turn")
    controller.close()
    controller.close()
    assert backend.applied()[:2] == (0.0, 0.0) and backend.closed
    assert not controller.command(0.3, 0.0)
    assert not any(t.is_alive() for t in controller._threads)  # no thread left behind


def test_backend_none_drives_nothing(ros_node, topics):
    config, frames = topics
    config.backend = "none"
    drive = make_drive(config, ros_node, frames)
    assert isinstance(drive, NoDrive)
    assert drive.status()["left"] == 0.0 and drive.status()["backend"] == "none"


def test_min_duty_above_max_duty_is_a_config_error(ros_node, topics):
    config, frames = topics
    config.min_duty, config.max_duty = 0.8, 0.5
    with pytest.raises(ConfigError, match="drive.min_duty"):
        make_drive(config, ros_node, frames, source="robot.yaml")


def test_sim_wheel_speeds_invert_the_duty_mapping(topics):
    config, _ = topics
    backend = SimBackend(config)
    backend.set(config.min_duty * 0.9, -config.max_duty)
    assert backend.wheel_speeds() == (0.0, -config.max_wheel_speed)


def test_a_failing_backend_is_reported_and_leaves_the_motors_off(ros_node, topics):
    from flask_move_server.drive.backends.l298n import L298NBackend
    from tests.standins.gpio import RecordingGPIO

    config, frames = topics
    gpio = RecordingGPIO()
    base = make_drive(config, ros_node, frames, backend=L298NBackend(config, gpio=gpio))
    try:
        gpio.fail_on = "pwm_duty"
        base.command(0.3, 0.0)
        status = wait_for(lambda: base.status()["error"] and base.status(), message="the failure in /status")
        assert "switched off" in status["error"] and status["left"] == 0.0 and status["right"] == 0.0
        gpio.fail_on = None
        assert gpio.outputs == {}  # every pin released
        base.command(0.3, 0.0)
        status = base.status()
        assert status["left"] == 0.0 and not status["connected"] and gpio.outputs == {}  # nothing drives the pins
    finally:
        base.close()
