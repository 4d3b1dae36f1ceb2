"""The ROS 1 adapters: node lifecycle, navigation, pose, teleop. Only these import rospy."""

from flask_move_server.ros import numpy_later

numpy_later.install()  # before any module here imports rospy: genpy without numpy until it is used
