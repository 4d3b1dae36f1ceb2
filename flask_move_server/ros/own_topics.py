"""Publishing a topic again in a process that also listens to it (``--sim``'s /map, read by the server).

rospy knows a publisher by its node's URI, and a process has one node. When the simulation takes a
publisher away (a mode switch), the server's own subscriber of that topic drops its connection to
it only once that connection's receive thread runs again, and that thread may still be inside a
callback. If the same topic is published again before then, the master announces the same URI,
rospy finds a connection to it still listed, answers itself "already connected" and never connects
to the new publisher: its latched message (the next mode's map) never arrives, and ``GET /map``
says no map is published until the server restarts.

:func:`publisher` first closes whatever connection this process's subscriber still lists to this
very process on the topic (none can be alive: the topic is not published here at that moment), so
the announcement of the new publisher is followed by a fresh connection.
"""

import logging

import rospy
from rospy.impl.registration import get_topic_manager

log = logging.getLogger(__name__)


def publisher(name, data_class, **options):
    """A ``rospy.Publisher`` of ``name`` that this process's own subscriber of ``name`` will hear."""
    forget_own_connections(rospy.resolve_name(name))
    return rospy.Publisher(name, data_class, **options)


def forget_own_connections(resolved_name):
    """Close this process's subscriber connections to itself on ``resolved_name``, unless it publishes the
    topic now; returns how many were closed."""
    topics = get_topic_manager()
    subscriber = topics.get_subscriber_impl(resolved_name)
    if subscriber is None or topics.get_publisher_impl(resolved_name) is not None:
        return 0
    own = rospy.get_node_uri()
    stale = [connection for connection in subscriber.connections if connection.endpoint_id == own]
    for connection in stale:
        connection.close()  # rospy's cleanup callback takes it off the subscriber's list
    if stale:
        log.info("%s: closed %d connection(s) to this process's own publisher, gone since", resolved_name,
                 len(stale))
    return len(stale)
