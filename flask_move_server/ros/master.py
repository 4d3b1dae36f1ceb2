"""Talking to the ROS master's XML-RPC API with a timeout (rospy's has none)."""

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


def identity(caller_id, uri=None, timeout=2.0):
    """What tells this master from a restarted one (``/run_id``, else its pid), or None when it does not answer."""
    master = proxy(uri, timeout)
    try:
        code, _, run_id = master.getParam(caller_id, "/run_id")
        if code == 1:
            return "run_id:{}".format(run_id)
        code, _, pid = master.getPid(caller_id)
        return "pid:{}".format(pid) if code == 1 else None
    except (OSError, xmlrpc.client.Error):
        return None


def private_params(node_name, uri=None, timeout=2.0):
    """The private parameters of ``node_name`` (``/ns/name/...``) as a dict, {} if none or unreachable."""
    master = proxy(uri, timeout)
    try:
        code, _, value = master.getParam(node_name, node_name.rstrip("/") + "/")
    except (OSError, xmlrpc.client.Error):
        return {}
    return value if code == 1 and isinstance(value, dict) else {}
