"""The serial backend against a ros_arduino_bridge firmware stand-in over a real pty pair."""

import math

import pytest

from flask_move_server.config import DriveConfig, FramesConfig
from flask_move_server.drive import make_drive
from flask_move_server.drive.backends.serial import SerialBackend
from tests.conftest import wait_for
from tests.standins.firmware import FirmwareStandIn


@pytest.fixture
def firmware(tmp_path):
    fw = FirmwareStandIn(tmp_path / "ttyACM0")
    yield fw
    fw.close()


@pytest.fixture
def config(firmware):
    cfg = DriveConfig(backend="serial")
    cfg.serial.port = firmware.link
    cfg.serial.open_delay = 0.0
    cfg.serial.timeout = 1.0
    cfg.serial.reconnect_period = 0.1
    return cfg


@pytest.fixture
def arduino(config):
    backend = SerialBackend(config)
    yield backend
    backend.close()


def test_start_up_resets_the_encoders_and_stops_the_motors(arduino, firmware):
    assert arduino.connected
    assert firmware.commands[:2] == ["r", "m 0 0"]


def test_speeds_are_sent_as_ticks_per_pid_frame(arduino, firmware, config):
    arduino.set(0.5, -1.0)
    per_frame = config.max_wheel_speed * config.serial.ticks_per_rev / (2 * math.pi * config.wheel_radius) / 30.0
    assert firmware.motors == (round(0.5 * per_frame), -round(per_frame))
    arduino.set(0.0, 0.0)
    assert firmware.motors == (0, 0)


def test_encoder_counts_are_read(arduino, firmware):
    firmware.encoders = [1234, -567]
    assert arduino.read_encoders() == (1234, -567)


def test_the_command_in_force_is_repeated_before_the_firmware_times_out(arduino, firmware, config):
    config.serial.keepalive = 0.0
    arduino.set(0.5, 0.5)
    sent = len(firmware.motor_commands())
    arduino.read_encoders()
    assert len(firmware.motor_commands()) == sent + 1 and firmware.motor_commands()[-1] == firmware.motors != (0, 0)


def test_unplugged_means_stopped_and_it_reconnects_with_continuous_counts(arduino, firmware):
    firmware.encoders = [100, 200]
    assert arduino.read_encoders() == (100, 200)
    arduino.set(0.5, 0.5)
    firmware.unplug()
    arduino.set(0.6, 0.6)
    assert arduino.read_encoders() is None
    assert not arduino.connected and "lost" in arduino.error
    firmware.plug()
    firmware.encoders = [0, 0]
    counts = wait_for(arduino.read_encoders, message="the backend to reconnect")
    assert counts == (100, 200) and arduino.connected and arduino.error is None
    assert firmware.commands[0] == "r" and firmware.motors == firmware.motor_commands()[-1] != (0, 0)
    firmware.encoders = [10, 20]
    assert arduino.read_encoders() == (110, 220)


def test_a_missing_port_is_retried_not_fatal(tmp_path, config):
    config.serial.port = str(tmp_path / "nothing-here")
    backend = SerialBackend(config)
    try:
        assert not backend.connected and "cannot open" in backend.error
        assert backend.read_encoders() is None
    finally:
        backend.close()


def test_close_stops_the_motors_and_is_idempotent(arduino, firmware):
    arduino.set(0.5, 0.5)
    arduino.close()
    arduino.close()
    assert firmware.motors == (0, 0) and not arduino.connected


def test_the_base_controller_reports_encoder_odometry(ros_node, unique_name, config, firmware):
    config.cmd_vel_topic, config.odom_topic = unique_name + "/cmd_vel", unique_name + "/odom"
    frames = FramesConfig(odom=unique_name + "_odom", base_link=unique_name + "_base_link")
    base = make_drive(config, ros_node, frames)
    try:
        per_metre = config.serial.ticks_per_rev / (2 * math.pi * config.wheel_radius)
        wait_for(lambda: base.status()["odom"]["source"] == "encoders" and firmware.commands.count("e") > 1,
                 message="the controller to read the encoders")
        firmware.encoders = [int(round(per_metre)), int(round(per_metre))]  # both sides rolled 1 m
        odom = wait_for(lambda: base.status()["odom"]["x"] > 0.99 and base.status()["odom"], message="odometry")
        assert math.isclose(odom["x"], 1.0, abs_tol=1e-3) and abs(odom["y"]) < 1e-6 and odom["yaw"] == 0
        spin = int(round(math.pi * config.track_width / 2 * per_metre))  # a half turn on the spot
        firmware.encoders = [firmware.encoders[0] - spin, firmware.encoders[1] + spin]
        odom = wait_for(lambda: abs(base.status()["odom"]["yaw"]) > 3.1 and base.status()["odom"],
                        message="the turn")
        assert math.isclose(odom["x"], 1.0, abs_tol=1e-3)
        base.command(0.2, 0.0)
        assert base.status()["left"] > 0
        firmware.unplug()
        status = wait_for(lambda: not base.status()["connected"] and base.status(), message="the unplug")
        assert status["left"] == 0.0 and status["right"] == 0.0 and status["error"]
    finally:
        base.close()
