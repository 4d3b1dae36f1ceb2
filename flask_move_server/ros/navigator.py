"""Goals to move_base, through actionlib (or the plain topic), and how they go.

The state of the current goal is one of ``idle``, ``active``, ``canceling``,
``succeeded``, ``aborted``, ``canceled``, ``rejected``. Each goal gets a
sequence number, so a late callback of a replaced goal never overwrites the
state of the new one. ``canceling``: a cancel was sent and move_base has not
confirmed it yet (action mode; topic mode has no confirmation, so ``canceled``
at once). The first end of a goal is its end: when the ROS master stops
answering, a goal under way becomes ``aborted`` with a message (its cancel is
still sent), and a later word from move_base about it changes nothing.
:meth:`Navigator.when_ended` tells each goal's end, once, to whoever listens (happenings.py).
"""

import logging
import threading
import time
from collections import OrderedDict

import actionlib
import rospy
from actionlib import CommState, SimpleGoalState
from actionlib_msgs.msg import GoalID
from geometry_msgs.msg import PoseStamped
from move_base_msgs.msg import MoveBaseAction, MoveBaseActionGoal, MoveBaseGoal

from flask_move_server.core.errors import NavigationUnavailable, RosUnavailable
from flask_move_server.core.goal_endings import failure_sentence, replaced_end
from flask_move_server.process.log_limits import Throttled
from flask_move_server.ros import master
from flask_move_server.ros.action_status import read_status_lightly
from flask_move_server.ros.convert import pose_from_msg, pose_stamped, stamp_now, write_pose
from flask_move_server.ros.direct import direct_publisher
from flask_move_server.ros.goal_ends import (
    ACTIVE,
    CANCELED,
    CANCELING,
    HELD,
    IDLE,
    RECOVERING,
    STUCK,
    SUCCEEDED,
    TERMINAL,
    GoalEnds,
    end_of_replaced,
)
from flask_move_server.ros.goal_first import publish_goals_first
from flask_move_server.ros.goal_hold import GoalHold
from flask_move_server.ros.node import WAITING
from flask_move_server.ros.readiness import ServerReadiness

log = logging.getLogger(__name__)

GOAL_LINES_BURST = 20  # goal lines logged per 10 s; the rest of a storm is counted



class Navigator(GoalEnds, GoalHold):
    """Sends the robot to goals and tracks the current one."""

    cancel_patience = 5.0  # s without move_base's word on a cancel before /status asks whether it runs
    ack_patience = 5.0  # s without move_base's word on a new goal before it is given up (aborted)

    def __init__(self, config, frames, node, pose_tracker):
        self._config = config
        self._frame = frames.map
        self._node = node
        self._pose = pose_tracker
        self._cond = threading.Condition()
        # Held while a goal or a cancel is sent, so a cancel racing a goto cancels that goal, not the one before.
        self._sending = threading.Lock()
        self._seq = 0
        self._state = IDLE
        self._goal = None
        self._feedback_pose = None
        self._message = None
        self._ends = OrderedDict()  # seq -> (state, message, target) of the goals a newer one replaced
        self._cancel_sent = None
        self._client = None
        self._readiness = None
        self._goal_pub = None
        self._cancel_pub = None
        self._direct = []  # action mode: the goal and cancel publishers actionlib's share
        self._spare_message = None  # the next goal's MoveBaseGoal, built ahead
        self._build_next_goal = None  # goal_first's: the next goal's action goal, built ahead
        self._released = False
        self._unacknowledged = None  # (seq, sent at) of a goal move_base has not answered yet
        self._ack_watch = None
        self._closing = threading.Event()  # wakes the acknowledgement watch, which never waits on _cond
        self._closed = False
        self._aside = None  # a sentence (or "") while an ended goal is set aside: /status says idle
        self.trips = None  # a TripRecord keeping the goal under way on disk, or None
        self._end_listeners = []  # callback(seq, state, target, pose, why), see when_ended
        self._judge = None  # callback(seq, said) -> True when it held the aborted goal (see judge_aborts)
        self._goal_lines = Throttled(log, "goal lines", burst=GOAL_LINES_BURST)  # a goal storm: not 300 lines/s
        node.when_ready(self._setup)
        node.when_lost(self._master_lost)

    def _setup(self):
        if self._config.goal_interface == "action":
            action = rospy.remap_name(self._config.action)  # as actionlib names its topics
            # First, so that actionlib's goal and cancel publishers share their direct connections.
            self._direct = [direct_publisher(action + "/goal", MoveBaseActionGoal, 10),
                            direct_publisher(action + "/cancel", GoalID, 10)]
            client = actionlib.SimpleActionClient(self._config.action, MoveBaseAction)
            read_status_lightly(client.action_client)  # move_base's status array: only our goal's entry
            self._build_next_goal = publish_goals_first(client.action_client)
            self._readiness = ServerReadiness(client.action_client)
            self._spare_message = MoveBaseGoal()
            self._client = client
        else:
            self._goal_pub = direct_publisher(self._config.simple_goal_topic, PoseStamped, 1)
            self._cancel_pub = direct_publisher(self._config.action + "/cancel", GoalID, 1)

    def when_ended(self, callback):
        """Call ``callback(seq, state, target, pose, why)`` once for each goal that ends.

        ``state``: ``succeeded``, ``aborted`` (also a goal move_base lost, or one given up: see
        :meth:`abandon`), ``rejected`` or ``canceled`` (by a cancel, or replaced by a newer goal
        while under way: ``why`` says which); ``target`` the waypoint name or None, ``pose`` the
        goal's Pose2D, ``why`` the sentence ``wait`` gives (None when it arrived). Called in the
        thread that ended the goal (actionlib's, a request's), outside the navigator's locks: keep
        it short; an exception is logged. A goal whose end nobody can know (topic mode, never
        canceled) is never told.
        """
        self._end_listeners.append(callback)

    # commands ----------------------------------------------------------------

    def goto(self, goal):
        """Send ``goal`` (a Goal); returns its sequence number. Replaces any goal under way."""
        self._check_reachable()
        replaced = None
        try:
            with self._sending:
                with self._cond:
                    replaced = self._replaced_facts()
                    self._keep_end()
                    self._seq += 1
                    seq = self._seq
                    self._goal, self._state, self._feedback_pose, self._message = goal, ACTIVE, None, None
                    self._aside = None
                    if self._client is not None:
                        self._expect_acknowledgement(seq)
                    self._cond.notify_all()
                self._publish_goal(seq, goal)
        finally:
            self._tell_end(end_of_replaced(replaced))  # the replaced goal's end: after the new goal is on its way
        self._goal_lines.info("goal %d: %s %s", seq, goal.target or "pose", goal.pose.as_dict())
        if self.trips is not None:
            self.trips.started(goal)
        self._build_ahead()
        return seq

    def _publish_goal(self, seq, goal):
        """Goal ``seq`` to move_base (``_sending`` held): the action's goal, or the plain topic's pose."""
        if self._client is not None:
            _settle_last_goal(self._client)
            self._client.send_goal(
                self._goal_message(goal.pose),
                done_cb=lambda status, result: self._done(seq, status),
                active_cb=lambda: self._acknowledged(seq),
                feedback_cb=lambda feedback: self._feedback(seq, feedback),
            )
        else:
            self._goal_pub.publish(pose_stamped(goal.pose, self._frame, rospy.Time.now()))

    def _build_ahead(self):
        """The next goal's messages, built last: once this goal is on its way, and after the work that
        follows it, so that move_base's reader, woken by the goal, does not wait for a core behind them."""
        build_next_goal = self._build_next_goal
        if build_next_goal is not None:
            self._spare_message = MoveBaseGoal()
            build_next_goal()

    def _expect_acknowledgement(self, seq):
        """Lock held, goal ``seq`` about to be sent: the watch gives it up unless move_base answers in time."""
        self._unacknowledged = (seq, time.monotonic())
        if self._ack_watch is None:
            self._ack_watch = threading.Thread(target=self._watch_acknowledgements, name="goal-ack-watch",
                                               daemon=True)
            self._ack_watch.start()

    def cancel(self, seq=None):
        """Cancel the goal under way (goal ``seq`` only, when given), if any; True when one was (not when
        its cancel is already sent).

        Action mode: ``canceling`` until move_base confirms (preempted or recalled);
        topic mode: ``canceled`` at once. A goal still ``canceling`` gets its cancel sent again
        (move_base may have missed it), but that does not count as canceling a goal.
        """
        with self._sending:
            with self._cond:
                if self._state not in HELD or seq not in (None, self._seq):
                    return False
                seq, newly, held = self._seq, self._state != CANCELING, self._state == RECOVERING
                self._state = CANCELING if self._client is not None and not held else CANCELED
                if newly:
                    self._cancel_sent = time.monotonic()
                ended = self._end_of_current() if self._state == CANCELED else None
                self._cond.notify_all()
            if not held:  # a held goal's cancel went to move_base as it was held
                self._send_cancel()
        self._goal_lines.info("goal %d: cancel %s", seq, "requested" if newly else "sent again")
        self._tell_end(ended)
        return newly

    def _send_cancel(self):
        client, cancel_pub = self._client, self._cancel_pub
        if client is not None:
            client.cancel_goal()
        elif cancel_pub is not None:
            cancel_pub.publish(GoalID())

    def wait(self, seq, timeout):
        """Block until goal ``seq`` ends or ``timeout`` passes: ``(state, why)`` then.

        ``why`` is the sentence for a goal that ended without arriving (None otherwise). A goal
        a newer one replaced answers how it ended: ``canceled``, "replaced by a newer goal", when
        it was still under way; its own end when it had ended (arrived, say) just before.
        """
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._seq == seq and self._state not in TERMINAL and not self._released:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    break
                self._cond.wait(remaining)
            if self._seq != seq:
                return replaced_end(*self._ends.get(seq, (ACTIVE, None, None)))
            if self._state == RECOVERING:  # under way, as far as its waiting client is concerned
                return ACTIVE, None
            return self._state, self._why(self._state)

    def _why(self, state):
        """Lock held: the sentence for the current goal in ``state`` (None unless it failed)."""
        if state in (IDLE, ACTIVE, SUCCEEDED):
            return None
        target = self._goal.target if self._goal else None
        return self._message or self._unconfirmed_cancel() or failure_sentence(state, target)

    def release_waiters(self):
        """Wake every :meth:`wait`, now and from now on: the server is stopping."""
        with self._cond:
            self._released = True
            self._cond.notify_all()

    @property
    def active(self):
        """True while the goal is under way (or held while the robot gets itself out) and not yet asked to cancel."""
        return self._state in (ACTIVE, RECOVERING)

    def set_aside(self, why=None):
        """An ended goal is old news (the mode switched, the server restarted): ``/status`` says
        ``idle``, with ``why`` as its message, until the next goal. A goal under way is left alone."""
        with self._cond:
            if self._state not in HELD and (why or self._aside is None):  # a sentence said stays said
                self._aside = why or ""

    def status(self, reading=None):
        """The navigation part of ``/status``; ``reading``: the pose to measure from (else looked up)."""
        with self._cond:
            goal, state, seq, message = self._goal, self._state, self._seq, self._message
            message = message or self._unconfirmed_cancel()
            if self._aside is not None:
                goal, state, message = None, IDLE, self._aside or None
        return {
            "state": STUCK if state == RECOVERING else state,
            "message": message,
            "target": goal.target if goal else None,
            "goal": goal.pose.as_dict() if goal else None,
            "goal_id": seq or None,
            "distance_remaining": self._distance_remaining(goal, state, reading),
            "interface": self._config.goal_interface,
        }

    def _unconfirmed_cancel(self):
        """Why a goal is still ``canceling`` after ``cancel_patience`` (lock held), or None."""
        if self._state != CANCELING or time.monotonic() - self._cancel_sent < self.cancel_patience:
            return None
        return ("move_base has not confirmed the cancel for {:.0f} s: is it still running? The goal stays "
                "'canceling' until it answers or a new goal replaces it.".format(time.monotonic() - self._cancel_sent))

    def server_ready(self):
        """True when goals can be sent now (move_base answers, or topic mode); never waits."""
        if not self._node.connected:
            return False
        if self._client is None:
            return self._goal_pub is not None
        return self._readiness.ready_now()

    def close(self):
        """Release the action client's or the goal topic's connections. Idempotent."""
        with self._cond:
            self._closed = True
            self._closing.set()
            self._cond.notify_all()
        if self._ack_watch is not None:
            self._ack_watch.join(2.0)
        client, self._client = self._client, None
        topics = [self._goal_pub, self._cancel_pub] + self._direct
        self._direct = []
        if client is not None:
            ac = client.action_client
            topics += [ac.pub_goal, ac.pub_cancel, ac.status_sub, ac.result_sub, ac.feedback_sub]
        self._goal_pub = self._cancel_pub = None
        for topic in topics:
            if topic is not None:
                topic.unregister()

    # internals ---------------------------------------------------------------

    def _goal_message(self, pose):
        """The MoveBaseGoal to ``pose`` in the map frame, stamped now (``_sending`` held).

        Filled in from a message built after the previous goal was sent: building it (seven nested
        genpy objects, fourteen as it was done before) was the largest step between a ``/goto`` and
        its publish.
        """
        message, self._spare_message = self._spare_message, None
        if message is None:
            message = MoveBaseGoal()
        target = message.target_pose
        target.header.frame_id = self._frame
        stamp_now(target.header.stamp)
        write_pose(target.pose, pose)
        return message

    def check_ros(self):
        """RosUnavailable, saying why, unless this node is connected and its goal interface set up."""
        if not self._node.connected:
            raise RosUnavailable(self._why_not_connected())
        if self._client is None and self._goal_pub is None:
            raise RosUnavailable("The ROS node is still starting (or stopping); try again in a moment.")

    def _check_reachable(self):
        self.check_ros()
        if self._client is not None and not self._readiness.ready(self._config.server_wait):
            action = rospy.resolve_name(self._config.action)
            raise NavigationUnavailable(
                "move_base does not answer on the action '{}': is the navigation stack "
                "running (roslaunch flask_move_server navigation.launch)?".format(action)
            )

    def _why_not_connected(self):
        """The node has no master: still registering with one that answers (the first second, or --sim's
        own master starting), or none answers at all."""
        uri = self._node.master_uri
        if self._node.state == WAITING and master.identity("/" + self._node.name, uri, timeout=0.3) is not None:
            return "The server is still connecting to its ROS master at {}; try again in a moment.".format(uri)
        return "ROS is not reachable: no master answers at {} ({}). Start roscore, or set ROS_MASTER_URI.".format(
            uri, self._node.state)

    def _feedback(self, seq, feedback):
        pose = pose_from_msg(feedback.base_position.pose)
        with self._cond:
            if seq == self._seq:
                self._feedback_pose = pose
                self._unacknowledged = None

    def _distance_remaining(self, goal, state, reading=None):
        if goal is None:
            return None
        if state == SUCCEEDED:
            return 0.0
        reading = reading or self._pose.current()
        here = reading.pose if reading is not None else self._feedback_pose
        return None if here is None else round(here.distance_to(goal.pose), 3)



def _settle_last_goal(client, patience=1.0):
    """Wait until actionlib has marked an ended goal DONE before the next goal is sent.

    SimpleActionClient calls the done callback *before* it marks its goal DONE. A goal sent in
    between (the callback woke a waiting ``/goto``, whose client sent the next at once) gets that
    DONE instead: actionlib then logs "received DONE twice", never reports the new goal's end, and
    ``/status`` said ``active`` for ever. A goal still running is replaced as before.
    """
    handle = client.gh
    if handle is None or handle.get_comm_state() != CommState.DONE:
        return
    deadline = time.monotonic() + patience
    with client.done_condition:
        while client.simple_state != SimpleGoalState.DONE and time.monotonic() < deadline:
            client.done_condition.wait(0.05)
