"""Asking localization to look again, without moving: AMCL's ``request_nomotion_update``.

AMCL updates its filter only after ``update_min_d`` / ``update_min_a`` of motion; a robot that
backed out of a wedge may stand with its estimate pushed into the wall by odometry that counted
blocked wheels. AMCL's ``request_nomotion_update`` service (``std_srvs/Empty``,
amcl_node.cpp ``nomotionUpdateCallback``) makes its next scan update the filter anyway; a few of
them, a scan apart, let the laser pull the estimate back. Without AMCL (mapping: gmapping
corrects itself; idle: nobody localizes) there is no such service, and nothing is asked.
"""

import logging
import time

import rospy
from std_srvs.srv import Empty

log = logging.getLogger(__name__)

SERVICE = "request_nomotion_update"
TIMES = 3  # updates asked for
APART = 0.3  # s between them: a scan of an A1 (5.5-10 Hz) comes in between
WAIT = 0.5  # s for the service to answer at all


class NoMotionUpdate:
    """Calls AMCL's ``request_nomotion_update`` a few times (``service`` resolved in the node's namespace)."""

    def __init__(self, service=SERVICE, times=TIMES, apart=APART):
        self._service, self._times, self._apart = service, times, apart

    def __call__(self):
        """Ask; True when localization answered (False: there is none, or it did not answer)."""
        name = rospy.resolve_name(self._service)
        try:
            rospy.wait_for_service(name, timeout=WAIT)
            update = rospy.ServiceProxy(name, Empty)
            for index in range(self._times):
                if index:
                    time.sleep(self._apart)
                update()
        except (rospy.ROSException, rospy.ServiceException) as exc:
            log.info("no localization to ask for an update without motion (%s): %s", name, exc)
            return False
        log.info("asked localization for %d updates without motion (%s)", self._times, name)
        return True
