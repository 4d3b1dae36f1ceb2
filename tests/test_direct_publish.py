"""Goals and cancels written from the request's thread (ros/direct.py), with a real master and rospy."""

import socket
import threading

import actionlib
import pytest
import rospy
from move_base_msgs.msg import MoveBaseAction, MoveBaseActionGoal, MoveBaseGoal
from std_msgs.msg import String

from flask_move_server.ros.direct import DirectConnection, direct_publisher
from tests.conftest import wait_for

BIG = 256 * 1024  # a message larger than what a socket's buffers take while nobody reads


class StalledReader:
    """A subscriber whose reader stops at its first message until released; then keeps everything."""

    def __init__(self, topic):
        self.received = []
        self.stalled = threading.Event()
        self.release = threading.Event()
        self.sub = rospy.Subscriber(topic, String, self._on_message, queue_size=None)

    def stall(self, publisher):
        """Connect to ``publisher``, get its message 0 and stop reading there."""
        wait_for(lambda: publisher.get_num_connections() == 1, message="the subscriber to connect")
        publisher.publish(String(_message(0)))
        wait_for(self.stalled.is_set, message="the subscriber's reader to stall")

    def close(self):
        self.release.set()
        self.sub.unregister()

    def _on_message(self, msg):
        if not self.stalled.is_set():
            self.stalled.set()
            self.release.wait(30)
        self.received.append(msg.data)


def _message(i):
    return "{:05d}:".format(i) + chr(ord("a") + i % 26) * BIG


@pytest.fixture
def publisher(ros_node, unique_name):
    pub = direct_publisher("/{}/goal".format(unique_name), String, 5)
    yield pub
    pub.unregister()


def test_a_subscriber_that_stops_reading_never_holds_up_the_publisher_nor_garbles_what_it_gets(publisher):
    reader = StalledReader(publisher.resolved_name)
    try:
        reader.stall(publisher)
        count = 60  # 15 MB: far more than the socket's buffers hold
        done = threading.Event()

        def publish_all():
            for i in range(1, count + 1):
                publisher.publish(String(_message(i)))
            done.set()

        threading.Thread(target=publish_all, daemon=True).start()
        assert done.wait(20), "publish() waited for a subscriber that does not read"
        reader.release.set()
        wait_for(lambda: reader.received and reader.received[-1].startswith("{:05d}:".format(count)), timeout=20,
                 message="the last message to arrive")
    finally:
        reader.close()

    numbers = [int(text[:5]) for text in reader.received]
    assert numbers[0] == 0 and numbers[-1] == count
    assert numbers == sorted(set(numbers)), "messages arrived out of order or twice"
    assert all(text == _message(n) for n, text in zip(numbers, reader.received)), "a message arrived garbled"
    assert len(numbers) < count + 1, "nothing was dropped: the stall never filled the socket"


def test_a_subscriber_that_goes_away_while_stalled_leaves_the_publisher_working(publisher):
    gone = StalledReader(publisher.resolved_name)
    try:
        gone.stall(publisher)
        for i in range(1, 30):  # fills the socket: the rest waits for the writer
            publisher.publish(String(_message(i)))
        gone.sub.unregister()
    finally:
        gone.close()
    wait_for(lambda: publisher.get_num_connections() == 0, message="the gone subscriber's connection to close")

    later = []
    sub = rospy.Subscriber(publisher.resolved_name, String, lambda m: later.append(m.data[:5]))
    try:
        wait_for(lambda: publisher.get_num_connections() == 1, message="a new subscriber to connect")
        publisher.publish(String(_message(99)))
        wait_for(lambda: later == ["00099"], message="the new subscriber to get the next message")
    finally:
        sub.unregister()


def test_actionlibs_goal_publisher_made_afterwards_shares_the_direct_connections(ros_node, unique_name):
    from tests.standins.move_base import ScriptedMoveBase

    action = "/{}/move_base".format(unique_name)
    ours = [direct_publisher(action + "/goal", MoveBaseActionGoal, 10)]
    move_base = ScriptedMoveBase(action)
    client = actionlib.SimpleActionClient(action, MoveBaseAction)
    try:
        assert client.wait_for_server(rospy.Duration(10)), "the move_base stand-in did not answer"
        goal = MoveBaseGoal()
        goal.target_pose.header.frame_id = "map"
        goal.target_pose.pose.position.x = 1.25
        goal.target_pose.pose.orientation.w = 1.0
        client.send_goal(goal)
        wait_for(lambda: move_base.goals and move_base.goals[-1][1].target_pose.pose.position.x == 1.25,
                 message="the goal to reach move_base")
        connections = client.action_client.pub_goal.impl.connections
        assert connections and all(isinstance(c, DirectConnection) for c in connections)
    finally:
        client.cancel_all_goals()
        for topic in [client.action_client.pub_goal, client.action_client.pub_cancel, client.action_client.status_sub,
                      client.action_client.result_sub, client.action_client.feedback_sub] + ours:
            topic.unregister()
        move_base.shutdown()


def _writers():
    return [t for t in threading.enumerate() if t.name == "direct-writer"]


def test_a_subscriber_that_keeps_up_costs_no_writer_thread(publisher):
    got = []
    sub = rospy.Subscriber(publisher.resolved_name, String, lambda m: got.append(m.data))
    try:
        wait_for(lambda: publisher.get_num_connections() == 1, message="the subscriber to connect")
        for i in range(20):
            publisher.publish(String("goal {}".format(i)))
        wait_for(lambda: len(got) == 20, message="the subscriber to get every message")
        assert _writers() == [], "a writer thread was started for a socket that took every message"
    finally:
        sub.unregister()


def test_a_subscriber_connecting_as_the_topic_closes_is_hung_up_on(ros_node, unique_name):
    from rospy.impl.tcpros_base import TCPROSTransport
    from rospy.impl.tcpros_pubsub import TCPROSPub

    pub = direct_publisher("/{}/goal".format(unique_name), String, 5)
    impl = pub.impl
    pub.unregister()  # the last publisher of the topic: rospy closes the topic
    ours, subscriber_end = socket.socketpair()
    try:
        transport = TCPROSTransport(TCPROSPub(impl.resolved_name, String), impl.resolved_name)
        transport.set_socket(ours, "/late_subscriber")
        assert impl.add_connection(transport) is False
        subscriber_end.settimeout(5)
        assert subscriber_end.recv(1) == b"", "the late subscriber's socket was left open"
        assert _writers() == []
    finally:
        subscriber_end.close()
