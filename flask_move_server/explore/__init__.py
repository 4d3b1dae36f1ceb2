"""Exploration (issue 24): the robot maps a flat by itself. While SLAM (gmapping) grows the map, the
explorer asks :func:`~flask_move_server.explore.frontiers.survey` where known free space meets the
unknown (frontiers), sends move_base a goal at the best one the robot can reach, leaves out goals
that failed (a blacklist), and ends when no reachable frontier is left. ``frontiers.py`` is the pure,
vectorised part (numpy, no rospy, no Flask); ``explorer.py`` drives the robot with it.
"""
