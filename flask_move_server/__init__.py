"""flask-move-server: send a ROS 1 robot to named places over HTTP.

Importing the package is cheap and side-effect free: rospy, Flask, zeroconf and
RPi.GPIO are imported by the modules that use them, when they are used.
"""

__version__ = "0.1.0"
API_VERSION = "1"
