"""ROS messages without numpy until something uses numpy: ~14 MB less RSS at rest (issue 32).

genpy (every ROS message's base) imports numpy at its own import only to list numpy's number types
among the types a float field may hold, a list read by ``genpy.message.check_type`` alone, which
names the bad field once serialising a message has failed. The server has no use for numpy until
it explores (``explore/frontiers.py``), yet numpy is a fifth of its memory. :func:`install` has
``genpy.message`` loaded with numpy out of sight (only when numpy is not loaded yet), and gives it a
list of float types that holds numpy's as soon as numpy is loaded, so what genpy accepts and what
it says are as before. Installed by ``flask_move_server``'s import, before any of its modules
imports rospy (whichever does first); does nothing where genpy was loaded earlier.
"""

import importlib.abc
import importlib.machinery
import sys

MODULE = "genpy.message"
NUMPY_FLOATS = ("float32", "float64", "int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64")


class FloatTypes:
    """genpy's float types: the ones it listed, and numpy's (as it lists them) once numpy is loaded."""

    def __init__(self, listed):
        self.listed = tuple(listed)

    def __contains__(self, kind):
        if kind in self.listed:
            return True
        numpy = sys.modules.get("numpy")
        return numpy is not None and kind in tuple(getattr(numpy, name) for name in NUMPY_FLOATS)

    def __iter__(self):
        return iter(self.listed)


class _Hiding(importlib.abc.Loader):
    """Runs genpy.message's loader with numpy unimportable, then hands it :class:`FloatTypes`."""

    def __init__(self, loader):
        self.loader = loader

    def create_module(self, spec):
        return self.loader.create_module(spec)

    def exec_module(self, module):
        if "numpy" in sys.modules:  # loaded meanwhile (or a reload): genpy as it comes
            self.loader.exec_module(module)
            return
        sys.modules["numpy"] = None  # "import numpy" raises ImportError: genpy takes its no-numpy branch
        try:
            self.loader.exec_module(module)
        finally:
            if sys.modules.get("numpy", 0) is None:
                del sys.modules["numpy"]
        if hasattr(module, "_valid_float_types"):
            module._valid_float_types = FloatTypes(module._valid_float_types)

    def __getattr__(self, name):  # get_data, get_filename, ... as the file's own loader has them
        return getattr(self.loader, name)


class _Finder(importlib.abc.MetaPathFinder):
    """Finds genpy.message as the path finder does, its loader wrapped; once, then it is gone."""

    def find_spec(self, name, path, target=None):
        if name != MODULE:
            return None
        _remove()
        if "numpy" in sys.modules:
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path, target)
        if spec is not None and spec.loader is not None:
            spec.loader = _Hiding(spec.loader)
        return spec


def _remove():
    sys.meta_path[:] = [f for f in sys.meta_path if not isinstance(f, _Finder)]


def install():
    """From now on the first import of genpy.message does not load numpy (a no-op once it is loaded)."""
    if MODULE in sys.modules or any(isinstance(f, _Finder) for f in sys.meta_path):
        return
    sys.meta_path.insert(0, _Finder())
