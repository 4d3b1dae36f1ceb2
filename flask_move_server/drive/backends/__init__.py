"""Motor backends: one small interface, each backend chosen by name.

A backend turns two signed commands, ``left`` and ``right`` in -1..1 of full
duty, into motor motion. Each lives in its own module and imports its
hardware library there (RPi.GPIO only in ``l298n``, pyserial only in
``serial``), so ``import flask_move_server`` needs neither. Modules register
themselves with :func:`register`; :func:`create` builds one by name.
"""

import importlib

from flask_move_server.core.errors import DriveError

# ``drive.backend: none``: another node drives the base, so no backend is built (drive.NoDrive).
NONE = "none"
# name -> module that registers it (imported only when that backend is chosen)
_MODULES = {
    "l298n": "flask_move_server.drive.backends.l298n",
    "serial": "flask_move_server.drive.backends.serial",
    "sim": "flask_move_server.drive.backends.sim",
}
_REGISTRY = {}


class MotorBackend:
    """What every backend offers: ``set``, ``stop``, ``close`` (idempotent).

    ``closed_loop`` backends take -1..1 as a fraction of the top wheel speed
    (their controller holds it), open-loop ones as a PWM duty.
    """

    name = "?"
    closed_loop = False
    has_encoders = False
    connected = True
    error = None

    def set(self, left, right):
        """Apply signed commands (-1..1) to the left and right sides."""
        raise NotImplementedError

    def stop(self):
        """Stop both sides now."""
        self.set(0.0, 0.0)

    def read_encoders(self):
        """Cumulative (left, right) encoder ticks, or None without encoders."""
        return None

    def close(self):
        """Stop and release the hardware. Idempotent."""

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def register(name):
    """Class decorator: make a backend available under ``name``."""

    def decorate(cls):
        cls.name = name
        _REGISTRY[name] = cls
        return cls

    return decorate


def motor_names():
    """The backends that drive motors from this process (``--motor-backend`` of flask-move-base)."""
    return sorted(_MODULES)


def names():
    """Every name ``drive.backend`` accepts: the motor backends, then ``none``."""
    return motor_names() + [NONE]


def backend_class(name):
    """The class registered as ``name``; DriveError quoting an unknown name."""
    if name not in _MODULES:
        raise DriveError(
            "unknown motor backend {!r}; choose one of: {}".format(name, ", ".join(motor_names()))
        )
    importlib.import_module(_MODULES[name])
    return _REGISTRY[name]


def create(name, *args, **kwargs):
    """Build the backend registered as ``name``."""
    return backend_class(name)(*args, **kwargs)
