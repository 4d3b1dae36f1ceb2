"""``python -m flask_move_server.drive.safe_stop``: the L298N bridges off, from outside the server.

The units' ``ExecStopPost=``: after the server (or ``flask-move-base``) stopped,
however it stopped, every L298N enable and input pin the config names is driven
low, so no bridge is left powering a motor when the process died without its
own clean-up. The pins are held low as outputs, not released: an input would
float and could enable a bridge. With a config it cannot read, the built-in
pins are stopped (better a wrong pin low than a motor running).
"""

import argparse
import logging
import sys

from flask_move_server import config as config_mod
from flask_move_server.core.errors import ConfigError, MoveServerError
from flask_move_server.drive.backends import l298n

log = logging.getLogger(__name__)


def bridge_pins(config):
    """Every L298N EN, IN1 and IN2 pin (BCM) the config names."""
    pins = []
    for _key, channel in l298n.check_pins(config.drive.l298n, config.source):
        pins += [channel.en, channel.in1, channel.in2]
    return pins


def safe_stop(config_path=None, gpio=None):
    """Drive the bridges' enable and input pins low; returns the pins set, [] when not l298n."""
    try:
        config = config_mod.load(config_path)
    except ConfigError as exc:
        log.warning("%s; using the default L298N pins", exc)
        config = config_mod.Config()
        config.drive.backend = "l298n"
    if config.drive.backend != "l298n":
        return []
    pins = bridge_pins(config)
    gpio = gpio if gpio is not None else l298n.import_gpio()
    gpio.setwarnings(False)
    gpio.setmode(gpio.BCM)
    for pin in pins:
        gpio.setup(pin, gpio.OUT, initial=gpio.LOW)
        gpio.output(pin, gpio.LOW)
    return pins


def main(argv=None, prog="python -m flask_move_server.drive.safe_stop"):
    """Stop the bridges the config names; exit status 0, or 1 when GPIO cannot be driven."""
    parser = argparse.ArgumentParser(prog=prog, description="Drive the L298N enable and input pins low.")
    parser.add_argument("--config", metavar="FILE", help="server config naming the pins (default: built-in pins)")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        pins = safe_stop(args.config)
    except MoveServerError as exc:
        print("safe-stop: {}".format(exc), file=sys.stderr)
        return 1
    print("safe-stop: " + ("GPIO {} low".format(", ".join(map(str, pins))) if pins else "no L298N pins to stop"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
