"""The L298N backend on a recording stand-in of RPi.GPIO: the pin truth table, and safe release."""

import sys

import pytest

from flask_move_server.config import DriveConfig, MotorChannelConfig
from flask_move_server.core.errors import ConfigError, DriveError
from flask_move_server.drive.backends import create
from flask_move_server.drive.backends.l298n import L298NBackend
from tests.standins.gpio import HIGH, LOW, RecordingGPIO, install

FORWARD, REVERSE = (HIGH, LOW), (LOW, HIGH)


def pins(gpio, channel):
    """(IN1, IN2, EN duty %) of one channel as the bridge sees it."""
    return gpio.outputs[channel.in1], gpio.outputs[channel.in2], gpio.duty(channel.en)


def side(gpio, config, name):
    return [pins(gpio, c) for c in getattr(config.l298n, name)]


@pytest.fixture
def rig():
    config = DriveConfig(backend="l298n")
    gpio = RecordingGPIO()
    backend = L298NBackend(config, gpio=gpio)
    yield config, gpio, backend
    backend.close()


def test_start_up_sets_bcm_mode_and_every_pin_low_before_any_pwm(rig):
    config, gpio, _ = rig
    assert gpio.mode == gpio.BCM
    setups = [c for c in gpio.calls if c[0] == "setup"]
    assert len(setups) == 12 and all(c[2] == gpio.OUT and c[3] == LOW for c in setups)
    assert all(d == 0 for c in gpio.calls if c[0] == "pwm_start" for d in [c[2]])
    frequencies = {c[2] for c in gpio.calls if c[0] == "pwm"}
    assert frequencies == {config.l298n.pwm_frequency}


def test_forward_drives_in1_high_in2_low_and_duty_on_en(rig):
    config, gpio, backend = rig
    backend.set(0.5, 0.5)
    assert side(gpio, config, "left") == [FORWARD + (50.0,)] * 2
    assert side(gpio, config, "right") == [FORWARD + (50.0,)] * 2


def test_reverse_swaps_the_direction_pins(rig):
    config, gpio, backend = rig
    backend.set(-0.7, -0.7)
    assert side(gpio, config, "left") == [REVERSE + (70.0,)] * 2
    assert side(gpio, config, "right") == [REVERSE + (70.0,)] * 2


@pytest.mark.parametrize("left,right,left_dir,right_dir", [
    (-0.4, 0.4, REVERSE, FORWARD),  # turn left (counter-clockwise) on the spot
    (0.4, -0.4, FORWARD, REVERSE),  # turn right
    (0.3, 0.9, FORWARD, FORWARD),  # gentle left arc
])
def test_turns_drive_each_side_its_own_way(rig, left, right, left_dir, right_dir):
    config, gpio, backend = rig
    backend.set(left, right)
    assert side(gpio, config, "left") == [left_dir + (abs(left) * 100,)] * 2
    assert side(gpio, config, "right") == [right_dir + (abs(right) * 100,)] * 2


def test_duty_is_capped_at_full(rig):
    config, gpio, backend = rig
    backend.set(1.7, -3.0)
    assert side(gpio, config, "left") == [FORWARD + (100.0,)] * 2
    assert side(gpio, config, "right") == [REVERSE + (100.0,)] * 2


def test_brake_stop_shorts_the_motor_with_en_high():
    config = DriveConfig(backend="l298n")
    config.l298n.stop_mode = "brake"
    gpio = RecordingGPIO()
    with L298NBackend(config, gpio=gpio) as backend:
        backend.set(0.6, -0.6)
        backend.stop()
        assert side(gpio, config, "left") == [(LOW, LOW, 100.0)] * 2
        assert side(gpio, config, "right") == [(LOW, LOW, 100.0)] * 2


def test_coast_stop_lets_the_motor_run_free_with_en_low():
    config = DriveConfig(backend="l298n")
    config.l298n.stop_mode = "coast"
    gpio = RecordingGPIO()
    with L298NBackend(config, gpio=gpio) as backend:
        backend.set(0.6, -0.6)
        backend.stop()
        assert side(gpio, config, "left") == [(LOW, LOW, 0.0)] * 2
        assert side(gpio, config, "right") == [(LOW, LOW, 0.0)] * 2


def test_an_inverted_channel_turns_the_other_way():
    config = DriveConfig(backend="l298n")
    config.l298n.left[1].invert = True
    gpio = RecordingGPIO()
    with L298NBackend(config, gpio=gpio) as backend:
        backend.set(0.5, 0.5)
        assert side(gpio, config, "left") == [FORWARD + (50.0,), REVERSE + (50.0,)]
        assert side(gpio, config, "right") == [FORWARD + (50.0,)] * 2


def test_one_channel_per_side_is_enough():
    config = DriveConfig(backend="l298n")
    config.l298n.left = [MotorChannelConfig(5, 6, 26)]
    config.l298n.right = [MotorChannelConfig(9, 10, 11)]
    gpio = RecordingGPIO()
    with L298NBackend(config, gpio=gpio) as backend:
        backend.set(0.4, -0.4)
        assert side(gpio, config, "left") == [FORWARD + (40.0,)]
        assert side(gpio, config, "right") == [REVERSE + (40.0,)]


def test_close_leaves_every_pin_low_and_cleans_up_only_our_pins_once(rig):
    config, gpio, backend = rig
    backend.set(0.8, 0.8)
    backend.close()
    backend.close()
    ours = {p for c in config.l298n.left + config.l298n.right for p in (c.in1, c.in2, c.en)}
    cleanups = [c for c in gpio.calls if c[0] == "cleanup"]
    assert len(cleanups) == 1 and set(cleanups[0][1]) == ours  # never a bare cleanup(): other pins are not ours
    assert set(gpio.cleaned) == ours
    stops = {c[1] for c in gpio.calls if c[0] == "pwm_stop"}
    assert stops == {c.en for c in config.l298n.left + config.l298n.right}
    last_levels = {}
    for call in gpio.calls:
        if call[0] == "output":
            last_levels[call[1]] = call[2]
    assert set(last_levels) == ours and set(last_levels.values()) == {LOW}
    backend.set(1.0, 1.0)  # after close: nothing moves
    assert gpio.outputs == {}


def test_a_gpio_failure_switches_the_bridges_off_and_says_so(rig):
    config, gpio, backend = rig
    backend.set(0.5, 0.5)
    gpio.fail_on = "pwm_duty"
    with pytest.raises(DriveError, match="motors switched off"):
        backend.set(0.9, 0.9)
    gpio.fail_on = None
    assert [c for c in gpio.calls if c[0] == "cleanup"], "pins were not released after the failure"
    assert all(call[2] == LOW for call in gpio.calls[-20:] if call[0] == "output")
    assert gpio.outputs == {}


def test_an_exception_in_the_with_block_releases_the_pins():
    config = DriveConfig(backend="l298n")
    gpio = RecordingGPIO()
    with pytest.raises(KeyError):
        with L298NBackend(config, gpio=gpio) as backend:
            backend.set(0.5, 0.5)
            raise KeyError("boom")
    assert gpio.outputs == {} and gpio.pwms == {}


def test_a_failure_during_start_up_releases_what_was_set_up():
    gpio = RecordingGPIO()
    gpio.fail_on = "pwm_start"
    with pytest.raises(DriveError, match="cannot set up the L298N pins"):
        L298NBackend(DriveConfig(backend="l298n"), gpio=gpio)
    gpio.fail_on = None
    assert gpio.outputs == {}


def test_duplicate_pins_are_refused_naming_both_keys():
    config = DriveConfig(backend="l298n")
    config.l298n.right[1].en = 22  # left[0].en
    gpio = RecordingGPIO()
    with pytest.raises(ConfigError) as info:
        L298NBackend(config, source="robot.yaml", gpio=gpio)
    message = str(info.value)
    assert "robot.yaml" in message and "drive.l298n.right[1].en" in message and "drive.l298n.left[0].en" in message
    assert gpio.calls == []  # nothing touched


@pytest.mark.parametrize("pin,reason", [(None, "missing"), (40, "0 to 27")])
def test_missing_or_invalid_pins_are_refused(pin, reason):
    config = DriveConfig(backend="l298n")
    config.l298n.left[0].in2 = pin
    with pytest.raises(ConfigError, match=reason) as info:
        L298NBackend(config, gpio=RecordingGPIO())
    assert "drive.l298n.left[0].in2" in str(info.value)


def test_without_rpi_gpio_the_error_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "RPi", None)
    monkeypatch.setitem(sys.modules, "RPi.GPIO", None)
    with pytest.raises(DriveError) as info:
        create("l298n", DriveConfig(backend="l298n"))
    message = str(info.value)
    assert "RPi.GPIO" in message and "rpi-lgpio" in message and "--motor-backend sim" in message


def test_the_backend_imports_the_real_module_name(monkeypatch):
    gpio = install(monkeypatch)
    with create("l298n", DriveConfig(backend="l298n")) as backend:
        backend.set(0.5, -0.5)
        assert gpio.duty(22) == 50.0 and gpio.outputs[17] == HIGH


def test_an_unknown_backend_name_is_quoted():
    with pytest.raises(DriveError, match="'l293d'.*l298n"):
        create("l293d", DriveConfig())


def test_importing_the_package_does_not_import_rpi_gpio():
    import subprocess

    code = "import sys, flask_move_server.app.cli, flask_move_server.drive; print('RPi' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_a_bad_pin_in_the_config_file_names_file_and_key():
    from flask_move_server import config

    data = {"drive": {"backend": "l298n", "l298n": {"left": [{"in1": 17, "in2": 27, "en": 40}]}}}
    with pytest.raises(ConfigError) as info:
        config.build(config.Config, data, source="robot.yaml")
    assert "robot.yaml" in str(info.value) and "drive.l298n.left[0].en" in str(info.value)
    data["drive"]["l298n"]["stop_mode"] = "float"
    data["drive"]["l298n"]["left"][0]["en"] = 22
    with pytest.raises(ConfigError, match="brake, coast"):
        config.build(config.Config, data, source="robot.yaml")
