"""The units' ExecStopPost: every L298N pin driven low, through the recording RPi.GPIO stand-in."""

import subprocess
import sys

import pytest

from flask_move_server.drive.safe_stop import safe_stop
from tests.standins.gpio import RecordingGPIO


def test_safe_stop_drives_every_bridge_pin_low(tmp_path):
    config = tmp_path / "robot.yaml"
    config.write_text("drive:\n  backend: l298n\n  l298n:\n    left: [{in1: 5, in2: 6, en: 26}]\n"
                      "    right: [{in1: 7, in2: 8, en: 9}]\n")
    gpio = RecordingGPIO()
    gpio.setmode(gpio.BCM)
    gpio.setup(26, gpio.OUT, initial=gpio.HIGH)  # as a crashed server may leave it
    pins = safe_stop(str(config), gpio)
    assert sorted(pins) == [5, 6, 7, 8, 9, 26]
    assert {pin: gpio.outputs[pin] for pin in pins} == {pin: gpio.LOW for pin in pins}
    assert not gpio.cleaned  # held low as outputs, not released to float


def test_safe_stop_does_nothing_for_other_backends(tmp_path):
    config = tmp_path / "robot.yaml"
    config.write_text("drive:\n  backend: sim\n")
    gpio = RecordingGPIO()
    assert safe_stop(str(config), gpio) == []
    assert gpio.calls == []


def test_safe_stop_falls_back_to_default_pins_on_a_broken_config(tmp_path):
    config = tmp_path / "robot.yaml"
    config.write_text("drive: {backend: l298n, typo: 1}\n")
    gpio = RecordingGPIO()
    pins = safe_stop(str(config), gpio)
    assert set(pins) == {17, 27, 22, 23, 24, 25, 12, 13, 19, 16, 20, 21}
    assert all(gpio.outputs[p] == gpio.LOW for p in pins)


@pytest.mark.parametrize("command", [
    ["flask_move_server.drive.safe_stop"],
    ["flask_move_server.systemd", "safe-stop"],  # what the units installed earlier run
])
def test_safe_stop_command(tmp_path, command):
    config = tmp_path / "robot.yaml"
    config.write_text("drive:\n  backend: none\n")
    proc = subprocess.run([sys.executable, "-m"] + command + ["--config", str(config)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0 and "no L298N pins" in proc.stdout
