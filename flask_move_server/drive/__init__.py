"""The motor drive: ``/cmd_vel`` → wheel commands, watchdog, odometry.

``make_drive`` builds what ``drive.backend`` names: :class:`NoDrive` for
``none`` (another node drives the base and publishes odometry, so this process
must not), otherwise a :class:`~flask_move_server.drive.controller.BaseController`
over the named motor backend (``l298n``, ``serial``, ``sim``). Importing this
package imports neither rospy nor RPi.GPIO.
"""

from flask_move_server.core.errors import ConfigError


class NoDrive:
    """Backend ``none``: another node drives the base; nothing is commanded here."""

    backend = None

    def status(self):
        """Motors are not ours: the applied command is 0."""
        return {"backend": "none", "left": 0.0, "right": 0.0, "watchdog_tripped": False, "command_age": None}

    def stop(self):
        """Nothing to stop: no motors are driven by this process."""

    def rearm(self):
        """Nothing to re-arm: the base controller that drives the motors is another node."""

    def close(self):
        """Nothing to release."""


def check_config(config, source="(config)"):
    """Checks spanning several drive keys; ConfigError naming the key."""
    if config.min_duty >= config.max_duty:
        raise ConfigError(source, "drive.min_duty", "must be below drive.max_duty ({} >= {})".format(
            config.min_duty, config.max_duty))


def make_drive(config, node, frames, source="(config)", backend=None, estop=None):
    """The drive for ``config`` (a DriveConfig): NoDrive or a running BaseController.

    ``backend`` overrides the one named in the config (tests, the simulation);
    ``estop``: the e-stop latch (drive/estop.py) under which every command is refused.
    Raises ConfigError for bad settings and DriveError when the hardware
    library is missing; on failure nothing is left holding a pin or a port.
    """
    if config.backend == "none" and backend is None:
        return NoDrive()
    check_config(config, source)
    from flask_move_server.drive.backends import create
    from flask_move_server.drive.controller import BaseController

    motors = backend if backend is not None else create(config.backend, config, source)
    try:
        return BaseController(config, node, motors, frames, estop=estop)
    except Exception:
        motors.close()
        raise
