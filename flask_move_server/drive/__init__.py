"""The motor drive: ``/cmd_vel`` → wheel commands, watchdog, odometry.

Backends are chosen by name (``drive.backend``): ``none`` here; the base
controller and the ``l298n``, ``serial`` and ``sim`` backends build on it.
"""


class NoDrive:
    """Backend ``none``: another node drives the base; nothing is commanded here."""

    backend = "none"

    def status(self):
        return {"backend": self.backend, "left": 0.0, "right": 0.0}

    def stop(self):
        """Nothing to stop: no motors are driven by this process."""

    def close(self):
        """Nothing to release."""
