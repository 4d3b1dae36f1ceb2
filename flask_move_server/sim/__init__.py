"""The simulated robot and world behind ``flask-move-server --sim``.

Pure parts (no rospy): ``occupancy`` (map_server maps), ``costmap``, ``planner``,
``follower`` (path following), ``body`` (the robot's true motion), ``laser``
(ray casting), ``demo_map``. ROS adapters: ``world`` (/map, /scan, AMCL
stand-in), ``move_base`` (the move_base stand-in), ``runner`` (start-up wiring
and the ROS master the simulation may own).
"""
