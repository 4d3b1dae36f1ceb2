"""The robot as a VDA 5050 2.0.0 vehicle on the owner's MQTT broker: a fleet manager drives it.

Topics ``<interface_name>/v<major>/<manufacturer>/<serial_number>/…`` on the robot's one MQTT
connection (mqtt/link.py):

- in: ``order`` (order.py checks it and decides, as the standard's Figure 8) and ``instantActions``
  (``cancelOrder``, ``startPause``, ``stopPause``, ``initPosition``, ``stateRequest``,
  ``factsheetRequest``); retained messages and payloads over 256 KB are refused;
- out: ``state`` on every change and at least every 30 s, ``visualization`` (the pose, at most
  1 Hz), ``connection`` (``ONLINE``; ``OFFLINE`` on a clean stop; the broker's last will
  ``CONNECTIONBROKEN``; retained) and ``factsheet`` (retained).

An order's base is driven as a run of the one executor (missions/executor.py, trigger
``vda5050``): ``/runs``, the page and Home Assistant see it; ``/stop``, the e-stop, a ``/goto``
end it. The run tells this vehicle each node reached (``watch``), under the executor's lock:
so this vehicle never calls the executor while it holds its own lock.
"""

import json
import logging
import math
import threading
import time

from flask_move_server.errors import MoveServerError
from flask_move_server.geometry import Pose2D
from flask_move_server.missions.route import Route
from flask_move_server.vda5050 import messages
from flask_move_server.vda5050.order import (
    HEADER,
    IGNORE,
    NEW,
    OrderBook,
    Refusal,
    check,
    stops_of,
    unsupported,
    within_reach,
)

log = logging.getLogger(__name__)

STATE_EVERY = 29.5  # s: the state is sent at least every 30 s (section 6.10), a late look (LOOK_EVERY) included
LOOK_EVERY = 0.25  # s between looks at what changed (driving, the e-stop, the battery)
VISUALIZATION_EVERY = 1.0  # s: the pose on ``visualization``, while it changes
KEPT_ACTION_STATES = 50
SPREAD_FOR_NO_SCORE = 0.5  # m of AMCL's position spread at which localizationScore reaches 0
ESTOP_TYPES = {"button": "MANUAL"}  # the e-stop's source → safetyState.eStop; others are REMOTE
FINISHED, FAILED = "FINISHED", "FAILED"
REPORTED = object()  # an instant action that reported its own end
RIDE_ALONG = ("batteryState", "information")  # no state of their own (section 6.10): sent with the next one
ENDED = {"failed": "The order ended on the robot: a node could not be reached (GET /runs says why).",
         "canceled": "The order ended on the robot: stopped there (POST /stop, the e-stop, a goal or the joystick).",
         "interrupted": "The order ended on the robot: the server stopped."}


class Vehicle:
    """One VDA 5050 vehicle: ``link`` the MQTT connection, ``robot`` the facade, ``runs`` the executor,
    ``store`` the active map's waypoints, ``modes`` the mode manager (None: the stack is someone else's)."""

    def __init__(self, link, config, robot_name, robot, runs, store, modes, factsheet, own_map="default",
                 clock=time.monotonic):
        """``own_map``: the mapId of the map the navigation stack was configured with (no named map in use)."""
        self._link, self._robot, self._runs, self._store, self._modes = link, robot, runs, store, modes
        self._own_map, self._clock = own_map, clock
        serial = config.serial_number or robot_name
        self.base = "{}/v{}/{}/{}".format(config.interface_name, config.version.split(".")[0],
                                          config.manufacturer, serial)
        self._headers = messages.Headers(config.version, config.manufacturer, serial)
        self._factsheet = factsheet
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._book = OrderBook()
        self._paused = False
        self._action_states = []
        self._errors = []
        self._run_id, self._driven = None, None  # the run driving the order's base, and its stops
        self._last_state, self._last_sent = None, 0.0
        self._last_pose, self._last_shown = None, 0.0
        self._closing = threading.Event()
        self._thread = None
        link.set_will(self.topic("connection"), self._connection("CONNECTIONBROKEN"))
        link.say_on_close(self.topic("connection"), lambda: self._connection("OFFLINE"))
        link.handle(self.topic("order"), self._on_order, max_payload=messages.MAX_PAYLOAD,
                    too_big=lambda size: self._too_big("order", size))
        link.handle(self.topic("instantActions"), self._on_instant_actions, max_payload=messages.MAX_PAYLOAD,
                    too_big=lambda size: self._too_big("instantActions", size))
        link.when_connected(self._connected)

    def topic(self, name):
        return "{}/{}".format(self.base, name)

    def start(self):
        log.info("VDA 5050: a vehicle on %s/ (orders from a fleet manager: docs/fleet.md)", self.base)
        self._thread = threading.Thread(target=self._loop, name="vda5050-state", daemon=True)
        self._thread.start()
        return self

    def close(self):
        self._closing.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=2)

    # out ---------------------------------------------------------------------

    def _connection(self, state):
        return self._json("connection", messages.connection(state))

    def _json(self, topic, body):
        return json.dumps(self._headers.stamp(topic, body), ensure_ascii=False)

    def _connected(self):
        """After each connect (paho's thread): ONLINE, the factsheet, the state."""
        self._link.publish(self.topic("connection"), self._connection("ONLINE"), retain=True)
        self._send_factsheet()
        self._last_state = None
        self._wake.set()

    def _send_factsheet(self):
        self._link.publish(self.topic("factsheet"), self._json("factsheet", self._factsheet), retain=True)

    def _loop(self):
        while not self._closing.is_set():
            self._wake.wait(LOOK_EVERY)
            self._wake.clear()
            if self._closing.is_set():
                return
            try:
                self._tell()
            except Exception:  # a bug in one look must not end the fleet manager's view of the robot
                log.exception("VDA 5050: could not build the state")

    def _tell(self):
        """The state when it changed (or STATE_EVERY passed); the pose on visualization when it moved."""
        body, position = self.state_body()
        now = self._clock()
        trigger = {k: v for k, v in body.items() if k not in RIDE_ALONG}
        trigger["agvPosition"] = position and (position["mapId"], position["positionInitialized"])  # known or not
        if trigger != self._last_state or now - self._last_sent >= STATE_EVERY:
            self._last_state, self._last_sent = trigger, now
            sent = dict(body, agvPosition=position) if position is not None else body
            self._link.publish(self.topic("state"), self._json("state", sent))
        if position is not None and position != self._last_pose and now - self._last_shown >= VISUALIZATION_EVERY:
            self._last_pose, self._last_shown = position, now
            self._link.publish(self.topic("visualization"), self._json("visualization", {"agvPosition": position}))

    def state_body(self):
        """``(state without header and agvPosition, agvPosition or None)``."""
        robot = self._robot
        nav, teleop, estop = robot.navigation_status(), robot.teleop_control.status(), robot.estop_status()
        battery, information = _battery(robot.battery_status())
        with self._lock:
            book = self._book
            body = {
                "orderId": book.order_id, "orderUpdateId": book.update_id,
                "lastNodeId": book.last_node_id, "lastNodeSequenceId": book.last_node_seq,
                "nodeStates": book.node_states(), "edgeStates": book.edge_states(),
                "actionStates": [dict(a) for a in self._action_states], "errors": [dict(e) for e in self._errors],
                "paused": self._paused,
            }
            run_id = self._run_id
        if run_id is not None and not body["paused"]:  # the run paused from the page or the API counts too
            body["paused"] = self._run_state(run_id) == "paused"
        # Read again after the order: a stop that came meanwhile (and dropped the order) is not "driving".
        nav, teleop = robot.navigation_status() if nav.get("state") == "active" else nav, robot.teleop_control.status()
        body.update({
            "driving": nav.get("state") == "active" or bool(teleop.get("active")),
            "newBaseRequest": False, "operatingMode": "MANUAL" if teleop.get("active") else "AUTOMATIC",
            "loads": [], "batteryState": battery, "information": information,
            "safetyState": {"eStop": ESTOP_TYPES.get(estop["source"], "REMOTE") if estop["latched"] else "NONE",
                            "fieldViolation": False},
        })
        return body, self._position()

    def _position(self):
        """``agvPosition`` from the pose tracker, or None while the pose is unknown."""
        tracker = self._robot.pose
        reading = tracker.current() if self._robot.node.connected else None
        if reading is None:
            return None
        fresh = tracker.age(reading) <= tracker.max_age
        map_id = self._active_map()
        position = {"x": round(reading.pose.x, 3), "y": round(reading.pose.y, 3),
                    "theta": round(reading.pose.yaw, 4), "mapId": map_id or "",
                    "positionInitialized": fresh and map_id is not None}
        spread = tracker.amcl_spread
        if spread is not None:
            position["localizationScore"] = round(max(0.0, 1.0 - math.hypot(spread[0], spread[1])
                                                      / SPREAD_FOR_NO_SCORE), 3)
        return position

    def _active_map(self):
        """The mapId of the map the robot navigates on (a named map, or the stack's own), or None."""
        if self._modes is None:
            return self._own_map
        status = self._modes.status()
        if status["mode"] != "navigation":
            return None
        return status["map"] or self._own_map

    # errors ------------------------------------------------------------------

    def _refuse(self, refusal, what="order"):
        """An order (or instant action) refused: its error is shown until an order is taken."""
        log.warning("VDA 5050: %s refused (%s): %s", what, refusal.error_type, refusal)
        with self._lock:
            self._errors = [e for e in self._errors if e["errorType"] != refusal.error_type][-9:]
            self._errors.append(refusal.as_error())
        self._wake.set()

    def _too_big(self, topic, size):
        self._refuse(Refusal("validationError", "A message of {} bytes on {} is larger than the {} bytes this "
                             "robot takes.".format(size, topic, messages.MAX_PAYLOAD), [("topic", topic)]), topic)

    # orders ------------------------------------------------------------------

    def _on_order(self, text):
        try:
            order = check(_parsed(text))
            unsupported(order)
            self._take(order)
        except Refusal as refusal:
            self._refuse(refusal)

    def _take(self, order):
        map_id = self._active_map()
        names = self._waypoint_names()
        with self._lock:
            kind = self._book.decide(order, lambda node: self._within_reach(node, names))
        if kind == IGNORE:
            log.info("VDA 5050: order %s update %d again: ignored", order["orderId"], order["orderUpdateId"])
            return
        if map_id is None:
            raise Refusal("orderError", "The robot is not navigating on a map, so it takes no order: choose a "
                          "map to navigate on first.", [("orderId", order["orderId"])])
        stops = stops_of(order["nodes"], map_id, names)
        self._accept(order, kind, stops)

    def _waypoint_names(self):
        try:
            return {w.name for w in self._store.all()}
        except MoveServerError:
            return set()

    def _within_reach(self, node, names):
        try:
            here = self._robot.current_pose()
        except MoveServerError:
            return False
        waypoint = None
        if "nodePosition" not in node and node["nodeId"] in names:
            w = self._store.get(node["nodeId"])
            waypoint = Pose2D(w.x, w.y, w.yaw)
        return within_reach(node, here, waypoint)

    def _accept(self, order, kind, stops):
        with self._lock:
            before, run_id = self._book.copy(), self._run_id if kind != NEW else None  # a new order: a new run
            released = {n["sequenceId"] for n in self._book.take(order, kind)}
            horizon = self._book.horizon
            if kind == NEW:
                self._action_states = []
            paused = self._paused
        drive = [s for s in stops if s.sequence_id in released]
        try:
            self._drive(order, drive, horizon, run_id, paused)
        except MoveServerError as exc:
            with self._lock:
                self._book = before
            raise Refusal("orderError", "The order could not start: {}".format(exc), [("orderId", order["orderId"])])
        with self._lock:
            self._errors = []
        log.info("VDA 5050: order %s update %d taken (%s): %d nodes to drive%s", order["orderId"],
                 order["orderUpdateId"], kind, len(drive), ", then a horizon" if horizon else "")
        self._wake.set()

    def _drive(self, order, stops, horizon, run_id, paused):
        """The run for the order's base: more stops for the one under way, or a new one."""
        labels, poses = [s.node_id for s in stops], [s.pose for s in stops]
        if run_id is not None and self._run_active(run_id):
            with self._lock:
                driven = self._driven
                driven.extend(stops)  # before the run can reach them
            try:
                self._runs.extend(run_id, labels, poses, open_end=horizon)
            except MoveServerError:
                with self._lock:
                    del driven[len(driven) - len(stops):]
                raise
            return
        if not stops:
            return
        driven = list(stops)
        with self._lock:
            self._driven = driven
        route = Route("VDA 5050 order {}".format(order["orderId"]), tuple(labels))
        run = self._runs.start(route, "vda5050", poses=poses, open_end=horizon, paused=paused,
                               watch=lambda what, value: self._watched(driven, what, value))
        with self._lock:
            if self._driven is driven:
                self._run_id = run["id"]

    def _run_active(self, run_id):
        return self._run_state(run_id) in ("running", "paused")

    def _run_state(self, run_id):
        try:
            return self._runs.get(run_id)["state"]
        except MoveServerError:
            return None

    def _watched(self, driven, what, value):
        """The run tells (under the executor's lock): a stop ``reached`` (its index), or the run ``ended``."""
        with self._lock:
            if driven is not self._driven:
                return
            if what == "reached":
                stop = driven[value]
                self._book.passed(stop.sequence_id, stop.node_id)
            elif what == "ended":
                self._run_id = None
                if value != "succeeded" and self._book.busy:
                    self._book.drop()
                    self._errors.append(Refusal("orderError", ENDED.get(value, ENDED["canceled"]),
                                                [("orderId", self._book.order_id)]).as_error())
        self._wake.set()

    # instant actions -----------------------------------------------------------

    def _on_instant_actions(self, text):
        try:
            actions = _instant_actions(_parsed(text))
        except Refusal as refusal:
            self._refuse(refusal, "instantActions")
            return
        for action in actions:
            self._act(action)

    def _act(self, action):
        act = {"cancelOrder": self._cancel_order, "startPause": self._start_pause, "stopPause": self._stop_pause,
               "initPosition": self._init_position, "stateRequest": self._state_request,
               "factsheetRequest": self._factsheet_request}.get(action["actionType"])
        if act is None:
            self._action_state(action, FAILED, "This robot does not do {}.".format(action["actionType"]))
            self._refuse(Refusal("orderError", "Instant action {} is not one this robot does (its factsheet lists "
                                 "them).".format(action["actionType"]), [("actionId", action["actionId"]),
                                                                        ("actionType", action["actionType"])]))
            return
        try:
            result = act(action)
        except (MoveServerError, Refusal) as exc:
            self._action_state(action, FAILED, str(exc))
            if isinstance(exc, Refusal):
                self._refuse(exc, action["actionType"])
            return
        if result is not REPORTED:
            self._action_state(action, FINISHED, result)

    def _action_state(self, action, status, result=None, then=None):
        """``action`` is ``status`` now; ``then()`` is done under the same lock (one state tells both)."""
        state = {"actionId": action["actionId"], "actionType": action["actionType"], "actionStatus": status}
        if result:
            state["resultDescription"] = str(result)[:200]
        with self._lock:
            states = [a for a in self._action_states if a["actionId"] != action["actionId"]]
            self._action_states = (states + [state])[-KEPT_ACTION_STATES:]
            if then is not None:
                then()
        self._wake.set()

    def _cancel_order(self, action):
        """RUNNING until the robot stands, then FINISHED with the order dropped, in one state (section 6.6.3)."""
        with self._lock:
            if not self._book.busy:
                raise Refusal("noOrderToCancel", "There is no order to cancel.", [("actionId", action["actionId"])])
            run_id, self._run_id, self._driven = self._run_id, None, None  # the run's end is ours: no error
        self._action_state(action, "RUNNING")
        if run_id is not None and self._run_active(run_id):
            self._runs.cancel(run_id)
        self._action_state(action, FINISHED, "The robot stopped; the order is dropped.", then=self._book.drop)
        return REPORTED

    def _start_pause(self, _action):
        with self._lock:
            self._paused, run_id = True, self._run_id
        if run_id is not None and self._run_active(run_id) and self._runs.get(run_id)["state"] == "running":
            self._runs.pause(run_id)
        return "Paused."

    def _stop_pause(self, _action):
        with self._lock:
            run_id = self._run_id
        if run_id is not None and self._run_active(run_id) and self._runs.get(run_id)["state"] == "paused":
            self._runs.resume(run_id)  # EStopLatched: the action fails, saying so
        with self._lock:
            self._paused = False
        return "Driving on."

    def _init_position(self, action):
        params = {p.get("key"): p.get("value") for p in action.get("actionParameters", []) if isinstance(p, dict)}
        for key in ("x", "y", "theta"):
            value = params.get(key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise Refusal("validationError", "initPosition needs a number '{}'.".format(key),
                              [("actionId", action["actionId"])])
        active = self._active_map()
        if params.get("mapId") != active:
            raise MoveServerError("mapId {!r} is not the map the robot navigates on ({}).".format(
                params.get("mapId"), active or "none"))
        if self._modes is None:
            raise MoveServerError("This server does not run localization; set the pose in RViz.")
        self._modes.set_pose(Pose2D(float(params["x"]), float(params["y"]), float(params["theta"])))
        if isinstance(params.get("lastNodeId"), str):
            with self._lock:
                self._book.last_node_id = params["lastNodeId"]
        return "Localization set."

    def _state_request(self, _action):
        with self._lock:
            self._last_state = None
        return "Sent."

    def _factsheet_request(self, _action):
        self._send_factsheet()
        return "Sent."


def _parsed(text):
    try:
        return json.loads(text)
    except ValueError as exc:
        raise Refusal("validationError", "Not JSON: {}".format(exc))
    except RecursionError:  # "[[[[…" nested deeper than Python's JSON reader goes
        raise Refusal("validationError", "Not JSON this robot reads: nested too deep.")


def _instant_actions(message):
    """The actions of an instantActions message, its fields checked; Refusal (validationError).

    The standard's 2.0.0 schema names the list ``actions``; 1.1 named it ``instantActions``, and some
    masters still send that with 2.0.0 (npm's vda-5050-lib 1.4): both are taken.
    """
    if isinstance(message, dict) and "actions" not in message and "instantActions" in message:
        message = dict(message, actions=message["instantActions"])
    if not isinstance(message, dict) or not isinstance(message.get("actions"), list):
        raise Refusal("validationError", "instantActions is a JSON object with a list 'actions'.")
    for key, kind in HEADER:
        if not isinstance(message.get(key), kind) or isinstance(message.get(key), bool):
            raise Refusal("validationError", "instantActions has no valid '{}'.".format(key))
    if len(message["actions"]) > messages.MAX_ACTIONS:
        raise Refusal("validationError", "instantActions holds {} actions; at most {} are taken.".format(
            len(message["actions"]), messages.MAX_ACTIONS))
    for action in message["actions"]:
        if not isinstance(action, dict) or not all(isinstance(action.get(k), str)
                                                   for k in ("actionId", "actionType", "blockingType")):
            raise Refusal("validationError", "Each instant action has text 'actionId', 'actionType' and "
                          "'blockingType'.")
        if not isinstance(action.get("actionParameters", []), list):
            raise Refusal("validationError", "actionParameters of {} is a list.".format(action["actionId"]),
                          [("actionId", action["actionId"])])
    return message["actions"]


def _battery(status):
    """``(batteryState, information)``: the battery's last reading, or 100 % and a word that none is heard."""
    if status is not None and status.get("percentage") is not None:
        state = {"batteryCharge": float(status["percentage"]), "charging": bool(status.get("charging"))}
        if status.get("voltage") is not None:
            state["batteryVoltage"] = float(status["voltage"])
        return state, []
    return {"batteryCharge": 100.0, "charging": False}, [{
        "infoType": "batteryUnknown", "infoLevel": "INFO",
        "infoDescription": "No battery reading is heard (battery.topic): batteryCharge says 100."}]
