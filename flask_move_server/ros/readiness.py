"""Whether move_base answers on the action, asked before every goal at the cost of a few comparisons.

actionlib's ``wait_for_server`` answers from move_base's last status message (whose node sent it)
and from the client's four connections to that node: goal and cancel publishers, result and
feedback subscribers. It walks all four lists and reads the clock on every call, on the request
thread, before the goal is published. That answer can only change when the status comes from
another node or a connection comes or goes, and rospy never changes a topic's connection list in
place: it swaps in a new list. So :class:`ServerReadiness` remembers a "ready" together with the
lists it was found on, and answers "ready" again while the same lists are there. Any change, a
move_base gone or restarted, asks actionlib again, so a missing move_base is still refused.
"""

import rospy


class ServerReadiness:
    """``ready(timeout)``: True when ``action_client``'s server answers, waiting up to ``timeout`` s."""

    def __init__(self, action_client):
        self._client = action_client
        self._ready_on = None  # the evidence a "ready" was found on

    def ready(self, timeout):
        """As actionlib's ``wait_for_server(Duration(timeout))``; without asking it while nothing changed."""
        evidence = self._evidence()
        if evidence[0] is not None and _same(evidence, self._ready_on):
            return True
        ready = self._client.wait_for_server(rospy.Duration(timeout))
        # The lists taken before the check: if one changed meanwhile, the next goal asks again.
        self._ready_on = evidence if ready and _same(evidence, self._evidence()) else None
        return ready

    def ready_now(self):
        """Whether the server answers at this instant, never waiting (``GET /health``, ``/status``).

        The same test as actionlib's ``wait_for_server`` makes on each pass of its loop, made once:
        that loop sleeps 10 ms before it looks at its timeout, so even ``ready(0.001)`` cost a
        ``/health`` 11 ms whenever move_base was absent.
        """
        evidence = self._evidence()
        server = evidence[0]
        if server is None:
            return False
        if _same(evidence, self._ready_on):
            return True
        results, feedback = evidence[3], evidence[4]
        return (any(c.callerid_pub == server for c in results) and any(c.callerid_pub == server for c in feedback)
                and self._client.pub_goal.impl.has_connection(server)
                and self._client.pub_cancel.impl.has_connection(server))

    def _evidence(self):
        client = self._client
        status = client.last_status_msg
        server = status._connection_header.get("callerid") if status is not None else None
        return (server, client.pub_goal.impl.connections, client.pub_cancel.impl.connections,
                client.result_sub.impl.connections, client.feedback_sub.impl.connections)


def _same(evidence, known):
    """The same server node and the very same connection lists (identity: rospy swaps, never edits).

    Written out, not as a loop: it runs before every goal is published.
    """
    return (known is not None and evidence[0] == known[0] and evidence[1] is known[1] and evidence[2] is known[2]
            and evidence[3] is known[3] and evidence[4] is known[4])
