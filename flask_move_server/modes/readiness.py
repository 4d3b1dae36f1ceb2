"""Is the stack's launch file runnable, and are its parts up? Asked before and while roslaunch starts.

Launch files are parsed with roslaunch's own loader (in this process, lazily imported), so a
missing package is named with the apt command that installs it before anything starts. Parts
are found through the ROS master's XML-RPC API with timeouts (rosgraph's has none): a topic
counts as published when one of its publishers is a live process of our stack.
"""

import collections
import logging
import os
import xmlrpc.client

from flask_move_server.core.errors import StackFailed
from flask_move_server.ros import master

CALLER = "/flask_move_server_stack"

# What the pre-check learnt of a launch file: the process names of the nodes that respawn, and
# whether it runs move_base (its stack then takes goals, and is ready once the action answers).
Launch = collections.namedtuple("Launch", "respawning runs_move_base")


def global_name(name):
    """``name`` resolved in this process's ROS namespace (``ROS_NAMESPACE``, default ``/``)."""
    if name.startswith("/"):
        return name
    namespace = os.environ.get("ROS_NAMESPACE", "").strip("/")
    return "/" + "/".join(part for part in (namespace, name) if part)


def apt_package(package):
    """The Debian/Ubuntu package of a ROS package: ``ros-noetic-map-server`` for ``map_server``."""
    return "ros-{}-{}".format(os.environ.get("ROS_DISTRO") or "noetic", package.replace("_", "-"))


def cannot_launch_message(package, node_type, why=""):
    """roslaunch's "cannot launch node of type [pkg/type]" as a sentence a user can act on."""
    if "Cannot locate node" in why:
        return "{} has no node {}: reinstall it (sudo apt install --reinstall {})".format(
            package, node_type, apt_package(package))
    return "{} is not installed: sudo apt install {}".format(package, apt_package(package))


def check_master(uri=None):
    """StackFailed unless a ROS master answers (roslaunch would start one of its own and own it)."""
    if master.identity(CALLER, uri, timeout=2.0) is None:
        raise StackFailed("no ROS master answers at {}: start it first (sudo systemctl start roscore)".format(
            uri or master.master_uri()))


def check_launch(roslaunch_args):
    """Parse the launch file roslaunch will run; StackFailed for a missing package or node.

    Returns a :class:`Launch`: the process names (``ns/name``, as roslaunch prints them) of the
    nodes that respawn, and whether a node of it is move_base.
    """
    try:
        import roslaunch.config
        import roslaunch.core
        import roslaunch.rlutil
    except ImportError:
        raise StackFailed("roslaunch is not installed: sudo apt install {} (or python3-roslaunch on Debian)".format(
            apt_package("roslaunch")))
    logging.getLogger("roslaunch").setLevel(logging.WARNING)  # its loader logs every node it adds

    files = [a for a in roslaunch_args if not a.startswith("-") and ":=" not in a]
    launch_args = [a for a in roslaunch_args if ":=" in a]
    try:
        (path,) = roslaunch.rlutil.resolve_launch_arguments(files)
        config = roslaunch.config.load_config_default([(path, launch_args)], None, verbose=False)
    except (roslaunch.core.RLException, ValueError) as exc:
        raise StackFailed("cannot load the launch file {}: {}".format(" ".join(files), _one_line(exc)))
    for node in config.nodes:
        problem = _missing_node(node.package, node.type)
        if problem:
            raise StackFailed(problem)
    return Launch({process_name(node) for node in config.nodes if node.respawn},
                  any((node.package, node.type) == ("move_base", "move_base") for node in config.nodes))


def process_name(node):
    """How roslaunch names a node's process in its output (without the ``-N`` counter)."""
    return (node.namespace.strip("/") + "/" + node.name).lstrip("/")


def _missing_node(package, node_type):
    import rospkg
    from roslib.packages import find_node

    try:
        found = find_node(package, node_type)
    except rospkg.ResourceNotFound:
        return cannot_launch_message(package, node_type)
    return None if found else cannot_launch_message(package, node_type, "Cannot locate node")


def missing(topics, pids, uri=None):
    """The topics in ``topics`` that no live process among ``pids`` publishes (all, if the master is away)."""
    proxy = master.proxy(uri, timeout=2.0)
    try:
        code, _, state = proxy.getSystemState(CALLER)
    except (OSError, xmlrpc.client.Error):
        return list(topics)
    publishers = dict(state[0]) if code == 1 else {}
    return [t for t in topics if not any(_node_pid(proxy, n) in pids for n in publishers.get(t, ()))]


def _node_pid(proxy, node):
    try:
        code, _, uri = proxy.lookupNode(CALLER, node)
        if code != 1:
            return None
        code, _, pid = master.proxy(uri, timeout=1.0).getPid(CALLER)
    except (OSError, xmlrpc.client.Error):
        return None
    return pid if code == 1 else None


def _one_line(exc):
    return " ".join(str(exc).split()) or type(exc).__name__
