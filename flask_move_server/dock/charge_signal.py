"""What says the robot charges: the battery's ``power_supply_status``, a GPIO pin, or nothing.

``dock.charge_detect``:

- ``battery`` (the default): ``sensor_msgs/BatteryState`` on ``battery.topic`` says CHARGING or
  FULL (``ros/battery.py``); a reading older than ``FRESH`` s, or none at all, says nothing;
- ``gpio``: a charge-detect input on ``dock.charge_gpio`` (BCM), high while the contacts carry the
  charger's voltage (through a divider or an optocoupler: 3.3 V at most), pulled down otherwise;
- ``none``: nothing says; the robot is docked, unconfirmed, when localization puts it on the dock.

Each is a callable giving ``"charging"``, ``"full"``, ``"off"`` or None (nothing says).
"""

from flask_move_server.core.errors import DriveError
from flask_move_server.drive.gpio import import_gpio, use_bcm

FRESH = 5.0  # s: an older battery reading says nothing of the contacts now


def battery_signal(monitor):
    """From a ros/battery.py BatteryMonitor."""
    return lambda: monitor.supply(FRESH)


class GpioSignal:
    """A charge-detect input: high while charging. Close once (idempotent)."""

    def __init__(self, pin, gpio=None):
        self.pin = pin
        self.gpio = gpio if gpio is not None else import_gpio(
            "dock.charge_gpio", "set dock.charge_detect: battery or none")
        try:
            use_bcm(self.gpio, "dock.charge_gpio")
            self.gpio.setup(pin, self.gpio.IN, pull_up_down=self.gpio.PUD_DOWN)
        except Exception as exc:
            raise DriveError("cannot read the charge-detect input on GPIO {}: {}".format(pin, exc))
        self._closed = False

    def __call__(self):
        if self._closed:
            return None
        return "charging" if self.gpio.input(self.pin) == self.gpio.HIGH else "off"

    def close(self):
        if not self._closed:
            self._closed = True
            self.gpio.cleanup([self.pin])


def no_signal():
    return None


def signal_of(config, monitor):
    """The callable ``dock.charge_detect`` names (a GpioSignal must be closed)."""
    if config.charge_detect == "gpio":
        return GpioSignal(config.charge_gpio)
    if config.charge_detect == "battery" and monitor is not None:
        return battery_signal(monitor)
    return no_signal
