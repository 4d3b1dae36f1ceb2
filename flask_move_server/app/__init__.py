"""The process: the command line, the wiring of every part, launching under roslaunch, living under systemd.

Nothing imports this package but the entry points (``__main__.py``, ``flask-move-base``, ``record-waypoints``).
"""
