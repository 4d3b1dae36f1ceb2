"""A stuck robot: knowing it, saying it, and backing out (issue 33).

On the real navigation stack a robot wedged on a door jamb kept "driving" in its open-loop
odometry while its wheels stood still, and every goal after that was aborted within seconds
("Rotate recovery can't rotate in place because there is a potential collision", then "Failed to
find a valid plan"): none of move_base's shipped recoveries can move a robot whose footprint
touches the map. This folder holds what the server does about it:

- ``scan_motion.py``: did the robot move as its odometry says? The laser's answer (pure);
- ``footprint.py``: the robot's footprint against the laser and the map: touching, clear behind (pure);
- ``detector.py``: the signs of a stuck robot, weighed into one verdict (pure);
- ``words.py``: what the owner reads (pure);
- ``back_out.py``: the one behaviour that frees it, a slow straight back-out (pure steps);
- ``relocate.py``: the position that slid with the odometry, put back where the laser fits (pure);
- ``recovery.py``: the state the server shows (``/status`` ``stuck``) and its signs weighed (no rospy);
- ``way_out.py``: its workers: the back-out with the goal held, then re-sent; the owner's back-out;
  the position put back (no rospy);
- ``watch.py``: its ROS side, ``/odom`` and the laser while the robot is told to move.
"""
