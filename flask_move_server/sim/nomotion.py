"""AMCL's ``request_nomotion_update`` service, as the sim's localization stand-in answers it.

AMCL (amcl_node.cpp ``nomotionUpdateCallback``) updates its filter on the next scan without
waiting for motion; the server asks for it after a back-out (``ros/relocalize.py``). The stand-in
answers the same service while it localizes (the navigation mode; in mapping, as with gmapping,
nobody answers): each request is one filter update of its belief (``sim/belief.py``).
"""

import logging
import threading

import rospy
from std_srvs.srv import Empty, EmptyResponse

from flask_move_server.ros.relocalize import SERVICE

log = logging.getLogger(__name__)


class NoMotionUpdateStandIn:
    """Serves ``request_nomotion_update`` for ``world`` (a SimWorld) until closed."""

    def __init__(self, node, world, service=SERVICE):
        self._world = world
        self._name = service
        self._lock = threading.Lock()
        self._service = None
        self._closed = False
        node.when_ready(self._setup)

    def _setup(self):
        with self._lock:
            if not self._closed:
                self._service = rospy.Service(self._name, Empty, self._update)

    def _update(self, request):
        self._world.belief.look_again(self._world.pose())
        return EmptyResponse()

    def close(self):
        """Stop answering. Idempotent."""
        with self._lock:
            self._closed = True
            service, self._service = self._service, None
        if service is not None:
            service.shutdown("the simulated navigation stopped")
