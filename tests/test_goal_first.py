"""actionlib's client publishing goals before building their tracking (ros/goal_first.py), real actionlib."""

import actionlib
import rospy
from actionlib_msgs.msg import GoalStatus
from move_base_msgs.msg import MoveBaseAction, MoveBaseGoal

from flask_move_server.ros.goal_first import publish_goals_first
from tests.standins.move_base import ABORT_X, ScriptedMoveBase


def _goal(x):
    goal = MoveBaseGoal()
    goal.target_pose.header.frame_id = "map"
    goal.target_pose.pose.position.x = x
    goal.target_pose.pose.orientation.w = 1.0
    return goal


def test_move_bases_answer_the_instant_a_goal_arrives_is_never_missed(ros_node, unique_name):
    action = "/{}/move_base".format(unique_name)
    move_base = ScriptedMoveBase(action, delay=0.0)  # succeeds (or aborts) as soon as the goal arrives
    client = actionlib.SimpleActionClient(action, MoveBaseAction)
    publish_goals_first(client.action_client)
    try:
        assert client.wait_for_server(rospy.Duration(10)), "the move_base stand-in did not answer"
        for i in range(20):
            client.send_goal(_goal(0.1 * i))
            assert client.wait_for_result(rospy.Duration(5)), "goal {}: its result never reached the client".format(i)
            assert client.get_state() == GoalStatus.SUCCEEDED
        client.send_goal(_goal(ABORT_X))
        assert client.wait_for_result(rospy.Duration(5))
        assert client.get_state() == GoalStatus.ABORTED and client.get_goal_status_text() == "no path"
        assert [round(g.target_pose.pose.position.x, 3) for _, g in move_base.goals] == \
            [round(0.1 * i, 3) for i in range(20)] + [ABORT_X]
    finally:
        ac = client.action_client
        for topic in (ac.pub_goal, ac.pub_cancel, ac.status_sub, ac.result_sub, ac.feedback_sub):
            topic.unregister()
        move_base.shutdown()


def test_a_goal_is_stamped_with_rospy_now_on_the_wall_clock_and_in_sim_time(ros_node):
    """stamp_now writes rospy.Time.now() into a message's own stamp: the wall clock, or /clock's
    time under /use_sim_time (a Gazebo robot), never the wall clock then."""
    import time

    from flask_move_server.ros.convert import stamp_now

    stamp = MoveBaseGoal().target_pose.header.stamp
    assert stamp_now(stamp) is stamp and abs(stamp.to_sec() - time.time()) < 1.0
    rospy.rostime._set_rostime(rospy.Time(1234, 5678))  # what rospy does on each /clock message
    try:
        assert (stamp_now(stamp).secs, stamp.nsecs) == (1234, 5678)
    finally:
        rospy.rostime._rostime_current = None  # back to the wall clock (_set_rostime takes Times only)
    assert abs(stamp_now(stamp).to_sec() - time.time()) < 1.0
