"""Backend ``none``: another node drives the base; nothing is commanded here."""

from flask_move_server.drive.backends import MotorBackend, register


@register("none")
class IdleBackend(MotorBackend):
    """Accepts commands and drives nothing: the applied command stays 0."""

    def __init__(self, config=None, source="(config)"):
        self.config = config

    def set(self, left, right):
        """Ignore the command: no motors belong to this process."""

