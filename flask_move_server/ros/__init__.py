"""The ROS 1 adapters: node lifecycle, navigation, pose, teleop. Only these import rospy."""
