"""Talking to the ROS master's XML-RPC API with a timeout (rospy's has none)."""

import collections
import os
import xmlrpc.client

DEFAULT_MASTER_URI = "http://localhost:11311"


def master_uri():
    """The ``ROS_MASTER_URI`` this process uses."""
    return os.environ.get("ROS_MASTER_URI") or DEFAULT_MASTER_URI


class _TimeoutTransport(xmlrpc.client.Transport):
    def __init__(self, timeout):
        super().__init__()
        self._timeout = timeout

    def make_connection(self, host):
        conn = super().make_connection(host)
        conn.timeout = self._timeout
        return conn


def proxy(uri=None, timeout=2.0):
    """An XML-RPC proxy of the master that gives up after ``timeout`` seconds."""
    return xmlrpc.client.ServerProxy(uri or master_uri(), transport=_TimeoutTransport(timeout))


class MasterIdentity(collections.namedtuple("MasterIdentity", "pid run_id")):
    """What tells a ROS master from a restarted one: its pid, and its ``/run_id`` once it has one."""

    __slots__ = ()

    def same_master(self, other):
        """True when ``other`` is this master seen again.

        roslaunch sets ``/run_id`` on a master started without one (``rosmaster --core``), so a
        run id appearing is not a new master; a different pid, or a different run id, is.
        """
        if self.pid != other.pid:
            return False
        return self.run_id is None or other.run_id is None or self.run_id == other.run_id

    def __str__(self):
        return "pid {}{}".format(self.pid, ", run_id {}".format(self.run_id) if self.run_id else "")


def identity(caller_id, uri=None, timeout=2.0):
    """The :class:`MasterIdentity` of the master at ``uri``, or None when it does not answer."""
    master = proxy(uri, timeout)
    try:
        code, _, pid = master.getPid(caller_id)
        if code != 1:
            return None
        code, _, run_id = master.getParam(caller_id, "/run_id")
        return MasterIdentity(pid, run_id if code == 1 else None)
    except (OSError, xmlrpc.client.Error):
        return None


def private_params(node_name, uri=None, timeout=2.0):
    """The private parameters of ``node_name`` (``/ns/name/...``) as a dict: {} if none, None if unreachable."""
    master = proxy(uri, timeout)
    try:
        code, _, value = master.getParam(node_name, node_name.rstrip("/") + "/")
    except (OSError, xmlrpc.client.Error):
        return None
    return value if code == 1 and isinstance(value, dict) else {}


def live_node(caller_id, node_name, uri=None, timeout=2.0):
    """``(pid, node_uri)`` of a node registered as ``node_name`` that answers, else None.

    A node that died without unregistering (SIGKILL, a power cut) stays registered with the master
    until another takes its name; its XML-RPC server no longer answers, so it reads as None here.
    """
    try:
        code, _, node_uri = proxy(uri, timeout).lookupNode(caller_id, node_name)
        if code != 1:
            return None
        code, _, pid = proxy(node_uri, timeout).getPid(caller_id)
    except (OSError, xmlrpc.client.Error):
        return None
    return (pid, node_uri) if code == 1 else None
