"""The one place RPi.GPIO is imported: for the L298N backend, the e-stop button and the safe stop.

Imported only when one of them is configured, so ``import flask_move_server`` never needs
RPi.GPIO. On a Pi 5, ``rpi-lgpio`` provides the same module.
"""

from flask_move_server.core.errors import DriveError

INSTALL = ("install RPi.GPIO on a Raspberry Pi 1-4 (sudo apt install python3-rpi.gpio), "
           "rpi-lgpio on a Pi 5 (sudo apt install python3-rpi-lgpio)")


def import_gpio(needed_by, otherwise):
    """The RPi.GPIO module; DriveError saying what needs it, what to install, and ``otherwise``."""
    try:
        import RPi.GPIO as GPIO
    except (ImportError, RuntimeError) as exc:  # RuntimeError: RPi.GPIO on a machine that is not a Pi
        raise DriveError("{} needs the RPi.GPIO module: {}, or {} ({})".format(needed_by, INSTALL, otherwise, exc))
    return GPIO


def use_bcm(gpio, what):
    """Set BCM pin numbering (our configs use it); DriveError if this process chose BOARD already."""
    gpio.setwarnings(False)
    mode = gpio.getmode()
    if mode not in (None, gpio.BCM):
        raise DriveError("GPIO numbering is already BOARD in this process; {} uses BCM".format(what))
    if mode is None:
        gpio.setmode(gpio.BCM)
