"""move_base's goal status array, read only for the goals our action client tracks.

move_base publishes a ``GoalStatusArray`` at 5 Hz and on every change of any goal, listing every
goal of the last few seconds (actionlib keeps ended goals 5 s). actionlib's client deserializes
each array in full, a Python object per goal, field and time stamp, then looks up only its own
goals in it. During a burst of goals that was the server's largest single cost (a fifth of its
busy time at 35 goals/s), on a thread that competes for the GIL with the next request.
:func:`read_status_lightly` swaps the client's status subscriber for one that takes the raw bytes,
walks the entries (three lengths each) and decodes only the entries of goals the client still
tracks; actionlib then gets an array of just those, which it treats exactly as the full one.
"""

import struct

import rospy
from actionlib_msgs.msg import GoalID, GoalStatus, GoalStatusArray

_U32 = struct.Struct("<I")
_STAMP = struct.Struct("<II")


def read_status_lightly(action_client):
    """Make ``action_client`` (an ``actionlib.ActionClient``) read its status topic as described above."""
    full = action_client.status_sub
    topic = full.resolved_name
    full.unregister()  # first: one topic has one message class in a rospy process
    action_client.status_sub = rospy.Subscriber(topic, rospy.AnyMsg, lambda raw: _on_status(action_client, raw))


def _on_status(action_client, raw):
    # actionlib keeps weak references to the goals it tracks; a replaced goal is gone from the list.
    tracked = {m.action_goal.goal_id.id.encode("utf-8") for m in action_client.manager._get_live_statuses()}
    array = GoalStatusArray(status_list=statuses_of(raw._buff, tracked))
    array._connection_header = raw._connection_header  # wait_for_server reads the server's callerid
    action_client._status_cb(array)


def statuses_of(buff, goal_ids):
    """The ``GoalStatus`` entries of a serialized ``GoalStatusArray`` whose goal id is in ``goal_ids`` (bytes)."""
    found = []
    if not goal_ids:
        return found
    (frame_len,) = _U32.unpack_from(buff, 12)  # header: seq, stamp (2), frame_id
    pos = 16 + frame_len
    (count,) = _U32.unpack_from(buff, pos)
    pos += 4
    for _ in range(count):
        (id_len,) = _U32.unpack_from(buff, pos + 8)  # goal_id: stamp (2), id
        end_of_id = pos + 12 + id_len
        (text_len,) = _U32.unpack_from(buff, end_of_id + 1)  # status (1 byte), text
        goal_id = bytes(buff[pos + 12:end_of_id])
        if goal_id in goal_ids:
            found.append(_status(buff, pos, goal_id, end_of_id, text_len))
        pos = end_of_id + 5 + text_len
    return found


def _status(buff, pos, goal_id, end_of_id, text_len):
    secs, nsecs = _STAMP.unpack_from(buff, pos)
    text = bytes(buff[end_of_id + 5:end_of_id + 5 + text_len]).decode("utf-8", "replace")
    return GoalStatus(goal_id=GoalID(stamp=rospy.Time(secs, nsecs), id=goal_id.decode("utf-8")),
                      status=buff[end_of_id], text=text)
