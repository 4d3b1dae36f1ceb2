"""actionlib's client publishes each goal first and builds its tracking right after.

actionlib's ``GoalManager.init_goal`` builds a goal's tracking (a state machine, with a status,
a goal id and a time stamp of its own, and a lock) and only then publishes the goal. On a
``/goto`` that put a few dozen microseconds of object building between the request and move_base
(``bench/bench_goals.py --stages``). :func:`publish_goals_first` makes ``action_client`` build
the same tracking just after the publish instead. Both happen while actionlib's list lock is
held, the lock its status, feedback and result callbacks take first, so move_base's first word on
the goal still finds it tracked, exactly as before.
"""

import weakref

import rospy
from actionlib.action_client import ClientGoalHandle, CommStateMachine
from std_msgs.msg import Header


def publish_goals_first(action_client):
    """Make ``action_client`` (an ``actionlib.ActionClient``) send goals as described above."""
    manager = action_client.manager

    def init_goal(goal, transition_cb=None, feedback_cb=None):
        return _init_goal(manager, goal, transition_cb, feedback_cb)

    manager.init_goal = init_goal


def _init_goal(manager, goal, transition_cb, feedback_cb):
    """actionlib's ``GoalManager.init_goal``, the publish moved before the tracking is built."""
    action_goal = manager.ActionGoal(header=Header(), goal_id=manager._generate_id(), goal=goal)
    action_goal.header.stamp = rospy.get_rostime()
    with manager.list_mutex:
        manager.send_goal_fn(action_goal)
        tracking = CommStateMachine(action_goal, transition_cb, feedback_cb, manager.send_goal_fn, manager.cancel_fn)
        manager.statuses.append(weakref.ref(tracking))
    return ClientGoalHandle(tracking)
