"""A wrong localization, on purpose: ``python -m tests.believer`` publishes each pose read from stdin
(``x y yaw [sigma]`` a line) as a pose estimate on ``/initialpose``, by default a sure one (1 cm, 0.01
rad: too narrow for the sim's AMCL stand-in to converge away from it), so a test can offset what the robot believes from
where it really is and watch a docking miss; ``ready`` on stdout once the sim listens."""

import sys
import time

import rospy
from geometry_msgs.msg import PoseWithCovarianceStamped

from flask_move_server.core.geometry import Pose2D
from flask_move_server.ros.initial_pose import estimate

SURE = 0.01


def main():
    rospy.init_node("believer", anonymous=True, disable_signals=True)
    pub = rospy.Publisher("initialpose", PoseWithCovarianceStamped, queue_size=1)
    deadline = time.monotonic() + 20
    while pub.get_num_connections() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    print("ready", flush=True)
    for line in sys.stdin:
        values = [float(v) for v in line.split()]
        sigma = values[3] if len(values) > 3 else SURE
        pub.publish(estimate(Pose2D(*values[:3]), "map", rospy.Time.now(), sigma ** 2, sigma ** 2))
        print("published", flush=True)


if __name__ == "__main__":
    main()
