"""move_base's status array read only for our goals (ros/action_status.py): the same entries, decoded."""

import io

import rospy
from actionlib_msgs.msg import GoalID, GoalStatus, GoalStatusArray

from flask_move_server.ros.action_status import statuses_of


def _status(i, state=GoalStatus.SUCCEEDED, text=""):
    return GoalStatus(goal_id=GoalID(stamp=rospy.Time(1700000000 + i, 1000 * i), id="/other-{}-1700.{}".format(i, i)),
                      status=state, text=text)


def _serialized(statuses, frame_id="map"):
    array = GoalStatusArray(status_list=statuses)
    array.header.seq, array.header.frame_id = 42, frame_id
    array.header.stamp = rospy.Time(1700000100, 5)
    buff = io.BytesIO()
    array.serialize(buff)
    return buff.getvalue()


def test_only_the_tracked_goals_entries_come_back_exactly_as_move_base_sent_them():
    ours = GoalStatus(goal_id=GoalID(stamp=rospy.Time(1700000050, 123456789), id="/flask_move_server-7-1700.050"),
                      status=GoalStatus.ACTIVE, text="driving to the kitchen — café corner")
    others = [_status(i, text="This goal was canceled because another goal was received") for i in range(150)]
    buff = _serialized(others[:80] + [ours] + others[80:], frame_id="a/long/frame_id")
    assert statuses_of(buff, {b"/flask_move_server-7-1700.050"}) == [ours]


def test_several_tracked_goals_come_back_in_the_arrays_order():
    statuses = [_status(i, state=i % 9) for i in range(20)]
    wanted = {s.goal_id.id.encode() for s in (statuses[3], statuses[17])}
    assert statuses_of(_serialized(statuses), wanted) == [statuses[3], statuses[17]]


def test_a_goal_move_base_no_longer_lists_is_not_there_and_an_empty_array_is_fine():
    assert statuses_of(_serialized([_status(i) for i in range(5)]), {b"/flask_move_server-1-1.0"}) == []
    assert statuses_of(_serialized([]), {b"/flask_move_server-1-1.0"}) == []
    assert statuses_of(_serialized([_status(1)]), set()) == []
