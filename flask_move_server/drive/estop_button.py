"""The physical e-stop button on a GPIO input (``drive.estop_pin``): a press latches the e-stop.

Wiring: a push button between the BCM pin and GND; the pin's internal pull-up
holds it high, a press pulls it low (active low). RPi.GPIO's edge detection
calls back on each falling edge (on its own thread); a press counts when the
pin still reads low ``drive.estop_debounce`` seconds later, so contact bounce
and a spike picked up from the motor wires do not latch, and a held button
does. A button already held at start-up latches at once. While the button is
held, releasing the latch is refused.

RPi.GPIO is imported (drive/gpio.py) only when a pin is configured (``rpi-lgpio`` on a Pi 5).
"""

import logging
import threading

from flask_move_server.core.errors import ConfigError, DriveError
from flask_move_server.drive.gpio import import_gpio as _import_gpio
from flask_move_server.drive.gpio import use_bcm

log = logging.getLogger(__name__)

SOURCE = "button"
def import_gpio():
    """The RPi.GPIO module; DriveError saying what to install when it is missing."""
    return _import_gpio("drive.estop_pin", "set drive.estop_pin: null on a machine without the button")


def check_pin(drive, source="(config)"):
    """ConfigError when ``drive.estop_pin`` is one of the L298N motor pins in use."""
    if drive.backend != "l298n":
        return
    for side in ("left", "right"):
        for i, channel in enumerate(getattr(drive.l298n, side)):
            for role in ("in1", "in2", "en"):
                if getattr(channel, role) == drive.estop_pin:
                    raise ConfigError(source, "drive.estop_pin", "GPIO {} is already drive.l298n.{}[{}].{}".format(
                        drive.estop_pin, side, i, role))


class EStopButton:
    """Watches the e-stop input pin and engages ``estop`` on a debounced press. Close once (idempotent)."""

    def __init__(self, drive, estop, source="(config)", gpio=None):
        check_pin(drive, source)
        self.pin = drive.estop_pin
        self.debounce = drive.estop_debounce
        self.estop = estop
        self.gpio = gpio if gpio is not None else import_gpio()
        self._closed = threading.Event()
        try:
            self._set_up()
        except Exception as exc:
            self._release()
            raise DriveError("cannot watch the e-stop button on GPIO {}: {}".format(self.pin, exc))
        estop.check_release_with(self._held_reason)
        if self.pressed():
            log.warning("the e-stop button on GPIO %d is pressed at start-up", self.pin)
            estop.engage(SOURCE)
        log.info("e-stop button on GPIO %d (pull-up, pressed = low, debounce %.3f s)", self.pin, self.debounce)

    def _set_up(self):
        gpio = self.gpio
        use_bcm(gpio, "drive.estop_pin")
        gpio.setup(self.pin, gpio.IN, pull_up_down=gpio.PUD_UP)
        gpio.add_event_detect(self.pin, gpio.FALLING, callback=self._edge)

    def pressed(self):
        """True while the button holds the pin low."""
        return self.gpio.input(self.pin) == self.gpio.LOW

    def _edge(self, channel):
        """RPi.GPIO's callback thread: a falling edge; latch if the pin is still low after the debounce."""
        if self._closed.wait(self.debounce):
            return
        if self.pressed():
            self.estop.engage(SOURCE)

    def _held_reason(self):
        if self._closed.is_set() or not self.pressed():
            return None
        return ("The e-stop button (GPIO {}) is still pressed: turn or pull it out first, then release "
                "the e-stop.".format(self.pin))

    def close(self):
        """Stop watching and hand the pin back. Idempotent."""
        if self._closed.is_set():
            return
        self._closed.set()
        self._release()

    def _release(self):
        for step in (lambda: self.gpio.remove_event_detect(self.pin), lambda: self.gpio.cleanup(self.pin)):
            try:
                step()
            except Exception as exc:
                log.debug("releasing the e-stop pin GPIO %s: %s", self.pin, exc)
