"""actionlib's client publishes each goal first and builds its tracking right after.

actionlib's ``GoalManager.init_goal`` builds a goal's message (the action goal, its header and
goal id, reading the clock twice) and its tracking (a state machine, with a status, a goal id and
a time stamp of its own, and a lock), and only then publishes the goal. On a ``/goto`` that put a
few dozen microseconds of object building between the request and move_base
(``bench/bench_goals.py --stages``). :func:`publish_goals_first` makes ``action_client`` fill in
an action goal built after the previous goal's request was done, read the clock once for its stamp and id,
publish it, and build the same tracking just after. Both the publish and the tracking happen
while actionlib's list lock is held, the lock its status, feedback and result callbacks take
first, so move_base's first word on the goal still finds it tracked, exactly as before. Goal ids
are actionlib's own (``caller-N-seconds``, from its counter), so they stay unique in the process.
"""

import weakref

import rospy
from actionlib import action_client as actionlib_client
from actionlib.action_client import ClientGoalHandle, CommStateMachine

from flask_move_server.ros.convert import stamp_now


def publish_goals_first(action_client):
    """Make ``action_client`` (an ``actionlib.ActionClient``) send goals as described above.

    Returns ``build_next()``, which builds the next goal's action goal: call it once a goal is on
    its way and the request's other work is done (a goal sent without one builds its own).
    """
    manager = action_client.manager
    spare = [manager.ActionGoal()]  # the next goal's action goal

    def init_goal(goal, transition_cb=None, feedback_cb=None):
        return _init_goal(manager, spare, goal, transition_cb, feedback_cb)

    def build_next():
        if not spare:
            spare.append(manager.ActionGoal())

    manager.init_goal = init_goal
    return build_next


def _init_goal(manager, spare, goal, transition_cb, feedback_cb):
    """actionlib's ``GoalManager.init_goal``, the publish moved before the tracking is built."""
    try:
        action_goal = spare.pop()
    except IndexError:  # two goals at once (one client sends one at a time): build this one now
        action_goal = manager.ActionGoal()
    stamp = stamp_now(action_goal.header.stamp)  # a Time of the goal's own, built ahead with it
    _set_goal_id(action_goal.goal_id, stamp)
    action_goal.goal = goal
    with manager.list_mutex:
        manager.send_goal_fn(action_goal)
        tracking = CommStateMachine(action_goal, transition_cb, feedback_cb, manager.send_goal_fn, manager.cancel_fn)
        manager.statuses.append(weakref.ref(tracking))
    return ClientGoalHandle(tracking)


def _set_goal_id(goal_id, stamp):
    """``GoalManager._generate_id``'s id and stamp, written into ``goal_id``, for the time ``stamp``."""
    number = actionlib_client.g_goal_id
    actionlib_client.g_goal_id = number + 1
    goal_id.id = "%s-%i-%.3f" % (rospy.get_caller_id(), number, stamp.to_sec())
    goal_id.stamp.secs, goal_id.stamp.nsecs = stamp.secs, stamp.nsecs
