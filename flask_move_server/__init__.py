"""flask-move-server: send a ROS 1 robot to named places over HTTP.

Importing the package is cheap: rospy, Flask, zeroconf and RPi.GPIO are imported by the modules
that use them, when they are used. Its one side effect: ROS's message library, when something
imports it, loads without numpy until numpy is used (ros/numpy_later.py: ~12 MB less at rest).
"""

from flask_move_server.ros import numpy_later

__version__ = "0.1.0"
API_VERSION = "1"

numpy_later.install()
