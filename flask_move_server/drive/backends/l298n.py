"""Backend ``l298n``: L298N H-bridges on the Raspberry Pi's GPIO (RPi.GPIO API, BCM).

Per L298N channel: direction on IN1/IN2, software PWM on EN. The truth table
(L298N datasheet): EN high with IN1 != IN2 turns the motor (IN1 high:
forward); EN high with IN1 == IN2 is a fast stop (brake); EN low lets the
motor coast, which is what the PWM off-phase does. Whatever happens (stop,
close, SIGTERM through cli's ExitStack, an exception) every EN and IN pin ends
low and our pins, only ours, are handed back with ``GPIO.cleanup(pins)``.

RPi.GPIO is imported (drive/gpio.py) when this backend is chosen: on a Pi 5 the
``rpi-lgpio`` package provides the same module.
"""

import logging
import threading

from flask_move_server.core.errors import ConfigError, DriveError
from flask_move_server.drive.backends import MotorBackend, register
from flask_move_server.drive.gpio import import_gpio as _import_gpio
from flask_move_server.drive.gpio import use_bcm

log = logging.getLogger(__name__)

def import_gpio():
    """The RPi.GPIO module; DriveError saying what to install when it is missing."""
    return _import_gpio("the l298n motor backend", "use --motor-backend sim on a machine without motors")


def check_pins(l298n, source="(config)"):
    """Every channel's pins as ``[(key, channel)]``; ConfigError naming missing or shared pins."""
    seen = {}
    channels = []
    for side in ("left", "right"):
        if not getattr(l298n, side):
            raise ConfigError(source, "drive.l298n." + side, "needs at least one channel (in1, in2, en)")
        for i, channel in enumerate(getattr(l298n, side)):
            key = "drive.l298n.{}[{}]".format(side, i)
            for role in ("in1", "in2", "en"):
                pin = getattr(channel, role)
                where = "{}.{}".format(key, role)
                if pin is None:
                    raise ConfigError(source, where, "missing: every channel needs in1, in2 and en")
                if isinstance(pin, bool) or not isinstance(pin, int) or not 0 <= pin <= 27:
                    raise ConfigError(source, where, "must be a BCM GPIO number, 0 to 27 (got {!r})".format(pin))
                if pin in seen:
                    raise ConfigError(source, where, "GPIO {} is already used by {}".format(pin, seen[pin]))
                seen[pin] = where
            channels.append((key, channel))
    return channels


class _Channel:
    """One L298N channel: two direction pins and a PWM enable pin."""

    def __init__(self, gpio, config, frequency, brake):
        self.gpio, self.config, self.brake = gpio, config, brake
        self.pins = (config.in1, config.in2, config.en)
        for pin in self.pins:
            gpio.setup(pin, gpio.OUT, initial=gpio.LOW)
        self.levels = {config.in1: gpio.LOW, config.in2: gpio.LOW}
        self.pwm = gpio.PWM(config.en, frequency)
        self.pwm.start(0)
        self.duty = 0.0

    def drive(self, duty):
        """Turn at signed ``duty`` (-1..1); 0 brakes or coasts as configured."""
        if self.config.invert:
            duty = -duty
        high, low = self.gpio.HIGH, self.gpio.LOW
        if duty > 0:
            self._direction(high, low)
        elif duty < 0:
            self._direction(low, high)
        else:
            self._direction(low, low)
        percent = min(abs(duty), 1.0) * 100.0
        if duty == 0:
            percent = 100.0 if self.brake else 0.0
        if percent != self.duty:
            self.pwm.ChangeDutyCycle(percent)
            self.duty = percent

    def _direction(self, in1, in2):
        for pin, level in ((self.config.in1, in1), (self.config.in2, in2)):
            if self.levels[pin] != level:
                self.gpio.output(pin, level)
                self.levels[pin] = level

    def release(self):
        """EN low (PWM stopped), IN1 and IN2 low; every step tried even if one fails."""
        low = self.gpio.LOW
        steps = [lambda: self.pwm.ChangeDutyCycle(0), self.pwm.stop]
        steps += [lambda p=p: self.gpio.output(p, low) for p in (self.config.en, self.config.in1, self.config.in2)]
        for step in steps:
            try:
                step()
            except Exception as exc:
                log.error("releasing GPIO %s: %s", self.pins, exc)


@register("l298n")
class L298NBackend(MotorBackend):
    """Two sides of one or more L298N channels each, on BCM-numbered GPIO."""

    def __init__(self, config, source="(config)", gpio=None):
        self.l298n = config.l298n
        channels = check_pins(self.l298n, source)
        self.gpio = gpio if gpio is not None else import_gpio()
        self._lock = threading.Lock()
        self._closed = False
        self.pins = [pin for _, c in channels for pin in (c.in1, c.in2, c.en)]
        self.sides = {"left": [], "right": []}
        try:
            self._set_mode()
            brake = self.l298n.stop_mode == "brake"
            for key, channel in channels:
                side = "left" if key.startswith("drive.l298n.left") else "right"
                self.sides[side].append(_Channel(self.gpio, channel, self.l298n.pwm_frequency, brake))
        except Exception as exc:
            self._release()
            raise DriveError("cannot set up the L298N pins {}: {}".format(self.pins, exc))

    def _set_mode(self):
        use_bcm(self.gpio, "the drive config")

    def set(self, left, right):
        """Apply signed duties; on any GPIO failure the bridges are switched off and DriveError raised."""
        with self._lock:
            if self._closed:
                return
            try:
                for channel in self.sides["left"]:
                    channel.drive(left)
                for channel in self.sides["right"]:
                    channel.drive(right)
            except Exception as exc:
                self._release()
                raise DriveError("GPIO failed, motors switched off: {}".format(exc))

    def close(self):
        """All EN and IN pins low, PWM stopped, our pins cleaned up. Idempotent."""
        with self._lock:
            self._release()

    def _release(self):
        if self._closed:
            return
        self._closed = True
        self.connected = False  # nothing drives the bridges any more: /status reports 0
        for channels in self.sides.values():
            for channel in channels:
                channel.release()
        try:
            self.gpio.cleanup(self.pins)
        except Exception as exc:
            log.error("GPIO.cleanup(%s) failed: %s", self.pins, exc)
