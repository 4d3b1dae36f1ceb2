"""A fleet manager's order driven by the robot: the kept order (order.py) and the run that drives its base.

The base is a run of the one executor (missions/executor.py, trigger ``vda5050``): released nodes
are its stops (a pose, or a waypoint's name), the horizon makes it wait at its last stop
(``open_end``), an update adds stops. The run tells each stop reached and its end (``watch``)
under the executor's lock: so nothing here calls the executor while holding the vehicle's lock.
An order that ends on the robot (``/stop``, the e-stop, a goal, a mode switch) is dropped with an
``orderError`` saying why; so is one waiting for its next release when the robot is sent elsewhere.
"""

import logging

from flask_move_server.core.errors import MoveServerError, RunConflict
from flask_move_server.core.geometry import Pose2D
from flask_move_server.missions.route import Route
from flask_move_server.vda5050.order import NEW, OrderBook, Refusal, stops_of, within_reach

log = logging.getLogger(__name__)

ACTIVE = ("running", "paused", "stuck")


class Driving:
    """The order and its run; ``lock`` and ``report`` the vehicle's, ``robot`` the facade, ``runs`` the
    executor, ``store`` the active map's waypoints, ``active_map()`` the mapId in force or None."""

    def __init__(self, lock, report, robot, runs, store, active_map):
        self._lock, self._report = lock, report
        self._robot, self._runs, self._store, self._active_map = robot, runs, store, active_map
        self.book = OrderBook()
        self.paused = False  # the fleet manager's startPause, until its stopPause (or the run resumed)
        self._run_id = None
        self._driven = None  # the run's stops by their index from its first: {index: Stop}, dropped once passed
        self._taking = False  # an order is being taken (its run may not be known yet) or canceled
        self._stops = 0  # the stops the run was given so far: the next one's index

    # taking an order ---------------------------------------------------------------

    def take(self, order):
        """Decide on ``order`` (checked) as Figure 8, and drive what it releases; Refusal otherwise."""
        waypoints = self._waypoints()
        with self._lock:
            kind = self.book.decide(order, lambda node: self._within_reach(node, waypoints))
        if kind == "ignore":
            log.info("VDA 5050: order %s update %d again: ignored", order["orderId"], order["orderUpdateId"])
            return
        map_id = self._active_map()
        if map_id is None:
            raise Refusal("orderError", "The robot is not navigating on a map, so it takes no order: choose a "
                          "map to navigate on first.", [("orderId", order["orderId"])])
        stops = stops_of(order["nodes"], map_id, waypoints)
        _fill_theta(order["nodes"], stops)
        self._accept(order, kind, stops)

    def _waypoints(self):
        try:
            return {w.name: Pose2D(w.x, w.y, w.yaw) for w in self._store.all()}
        except MoveServerError:
            return {}

    def _within_reach(self, node, waypoints):
        try:
            here = self._robot.current_pose()
        except MoveServerError:
            return False
        return within_reach(node, here, waypoints.get(node["nodeId"]))

    def _accept(self, order, kind, stops):
        with self._lock:
            before, run_id = self.book.copy(), self._run_id if kind != NEW else None  # a new order: a new run
            released = {n["sequenceId"] for n in self.book.take(order, kind)}
            horizon, paused, self._taking = self.book.horizon, self.paused, True
        drive = [s for s in stops if s.sequence_id in released]
        try:
            self._drive(order, drive, horizon, run_id, paused)
        except MoveServerError as exc:
            with self._lock:
                self.book, self._taking = before.caught_up(self.book), False
            raise Refusal("orderError", "The order could not start: {}".format(exc), [("orderId", order["orderId"])])
        with self._lock:
            self._taking = False
            self._report.order_taken(kind == NEW)
        log.info("VDA 5050: order %s update %d taken (%s): %d nodes to drive%s", order["orderId"],
                 order["orderUpdateId"], kind, len(drive), ", then a horizon" if horizon else "")

    def _drive(self, order, stops, horizon, run_id, paused):
        """The run for the order's base: more stops for the one under way, or a new one."""
        if run_id is not None and self._run_state(run_id) in ACTIVE:
            try:
                self._extend(run_id, stops, horizon)
                return
            except RunConflict:  # it ended just now (its last stop reached): the update starts a new run
                if self._run_state(run_id) in ACTIVE:
                    raise
        if stops:
            self._start(order, stops, horizon, paused)

    def _extend(self, run_id, stops, horizon):
        with self._lock:
            driven, first = self._driven, self._stops
            driven.update({first + i: stop for i, stop in enumerate(stops)})  # before the run can reach them
            self._stops += len(stops)
        try:
            self._runs.extend(run_id, [s.node_id for s in stops], [s.pose for s in stops], open_end=horizon)
        except MoveServerError:
            with self._lock:
                for i in range(first, first + len(stops)):
                    driven.pop(i, None)
                self._stops = first
            raise

    def _start(self, order, stops, horizon, paused):
        driven = dict(enumerate(stops))
        with self._lock:
            self._driven, self._stops = driven, len(stops)
        route = Route("VDA 5050 order {}".format(order["orderId"]), tuple(s.node_id for s in stops))
        run = self._runs.start(route, "vda5050", poses=[s.pose for s in stops], open_end=horizon, paused=paused,
                               watch=lambda what, value: self._watched(driven, what, value))
        with self._lock:
            if self._driven is driven:
                self._run_id = run["id"]

    def _run_state(self, run_id):
        try:
            return self._runs.get(run_id)["state"]
        except MoveServerError:
            return None

    # the run tells -------------------------------------------------------------------

    def _watched(self, driven, what, value):
        """Under the executor's lock: a stop ``reached`` (its index), or the run ``ended`` ((state, message))."""
        with self._lock:
            if driven is not self._driven:
                return
            if what == "reached":
                stop = driven.pop(value, None)
                if stop is not None:
                    self.book.passed(stop.sequence_id, stop.node_id)
                return
            self._run_id = None
            state, message = value
            if state != "succeeded" and self.book.busy:  # succeeded: what is left is an update's, starting now
                self._ended_on_the_robot(message or state)

    def _ended_on_the_robot(self, why):
        """Lock held: the order cannot go on; the fleet manager is told why, and nothing is left to do."""
        self.book.drop()
        self._report.note_error(Refusal("orderError", "The order ended on the robot: {}".format(why),
                                        [("orderId", self.book.order_id)]).as_error())

    def look(self):
        """From the state's thread: an order waiting for its next release (no run) ends when the robot
        is sent elsewhere (a goal, the joystick, another run); a resumed run ends the fleet manager's pause."""
        with self._lock:
            waiting, run_id = self.book.busy and self._run_id is None and not self._taking, self._run_id
        if run_id is not None:
            if self._run_state(run_id) == "running":
                with self._lock:
                    self.paused = False
            return
        if waiting:
            elsewhere = self._robot.busy_with() or (self._runs.active() and "Another run started.")
            if elsewhere:
                with self._lock:
                    if self.book.busy and self._run_id is None and not self._taking:
                        self._ended_on_the_robot(elsewhere)

    # instant actions ---------------------------------------------------------------

    def cancel(self, action, report):
        """cancelOrder: RUNNING until the robot stands, then FINISHED with the order dropped in one state."""
        with self._lock:
            if not self.book.busy:
                raise Refusal("noOrderToCancel", "There is no order to cancel.", [("actionId", action["actionId"])])
            run_id, self._run_id, self._driven = self._run_id, None, None  # the run's end is ours: no error
            self._taking = True
        report.action(action, "RUNNING")
        try:
            if run_id is not None and self._run_state(run_id) in ACTIVE:
                self._runs.cancel(run_id)
        except MoveServerError:  # it ended meanwhile: make sure the robot stands anyway
            self._robot.halt()
        report.action(action, "FINISHED", "The robot stopped; the order is dropped.", then=self._canceled)

    def _canceled(self):
        """Lock held: the order dropped by its cancelOrder."""
        self.book.drop()
        self._taking = False

    def pause(self):
        with self._lock:
            run_id = self._run_id
        if run_id is not None and self._run_state(run_id) == "running":
            self._runs.pause(run_id)
        with self._lock:
            self.paused = True

    def resume(self):
        with self._lock:
            run_id = self._run_id
        if run_id is not None and self._run_state(run_id) in ("paused", "stuck"):
            self._runs.resume(run_id)  # EStopLatched: the action fails, saying so
        with self._lock:
            self.paused = False

    def at_node(self, node_id):
        """initPosition's ``lastNodeId``: the robot stands on that node now."""
        with self._lock:
            self.book.last_node_id = node_id

    def run_paused(self):
        """Whether the order's run is paused (from the page, the API, or the fleet manager)."""
        with self._lock:
            run_id = self._run_id
        return run_id is not None and self._run_state(run_id) == "paused"


def _fill_theta(nodes, stops):
    """Each ``nodePosition`` without ``theta`` gets the heading the robot will take there: the state's
    nodeStates must carry one (2.0.0's schema requires it there)."""
    for node, stop in zip(nodes, stops):
        position = node.get("nodePosition")
        if position is not None and "theta" not in position and stop.pose is not None:
            position["theta"] = stop.pose.yaw  # in [-pi, pi] as atan2 gives it (rounded, it may leave that range)
