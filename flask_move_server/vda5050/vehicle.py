"""The robot as a VDA 5050 2.0.0 vehicle on the owner's MQTT broker: a fleet manager drives it.

Topics ``<interface_name>/v<major>/<manufacturer>/<serial_number>/…`` on the robot's one MQTT
connection (mqtt/link.py):

- in: ``order`` (order.py checks it, driving.py decides and drives it) and ``instantActions``
  (instant.py); retained messages and payloads over 256 KB are refused;
- out: ``state`` on every change and at least every 30 s, ``visualization`` (the pose, at most
  1 Hz), ``connection`` (``ONLINE``; ``OFFLINE`` on a clean stop; the broker's last will
  ``CONNECTIONBROKEN``; retained) and ``factsheet`` (retained).

One lock guards the kept order, the errors and the action states, so that one state shows them
as they were together; one thread looks four times a second at what changed.
"""

import json
import logging
import math
import threading
import time

from flask_move_server.process.log_limits import Throttled
from flask_move_server.vda5050 import messages
from flask_move_server.vda5050.charging import Charging
from flask_move_server.vda5050.driving import Driving
from flask_move_server.vda5050.instant import InstantActions
from flask_move_server.vda5050.order import Refusal, check, unsupported
from flask_move_server.vda5050.report import Report

log = logging.getLogger(__name__)

STATE_EVERY = 29.5  # s: the state is sent at least every 30 s (section 6.10), a late look (LOOK_EVERY) included
LOOK_EVERY = 0.25  # s between looks at what changed (driving, the e-stop, the battery) with an order or driving
IDLE_LOOK_EVERY = 1.0  # s between looks while the robot stands with no order (an e-stop wakes it at once)
VISUALIZATION_EVERY = 1.0  # s: the pose on ``visualization``, while it changes
SPREAD_FOR_NO_SCORE = 0.5  # m of AMCL's position spread at which localizationScore reaches 0
ESTOP_TYPES = {"button": "MANUAL"}  # the e-stop's source → safetyState.eStop; others are REMOTE
RIDE_ALONG = ("batteryState", "information")  # no state of their own (section 6.10): sent with the next one


class Vehicle:
    """One VDA 5050 vehicle: ``link`` the MQTT connection, ``robot`` the facade, ``runs`` the executor,
    ``store`` the active map's waypoints, ``modes`` the mode manager (None: the stack is someone else's)."""

    def __init__(self, link, config, robot_name, robot, runs, store, modes, factsheet, own_map="default",
                 clock=time.monotonic):
        """``own_map``: the mapId of the map the navigation stack was configured with (no named map in use)."""
        self._link, self._robot, self._modes = link, robot, modes
        self._own_map, self._clock = own_map, clock
        serial = config.serial_number or robot_name
        self.base = "{}/v{}/{}/{}".format(config.interface_name, config.version.split(".")[0],
                                          config.manufacturer, serial)
        self._headers = messages.Headers(config.version, config.manufacturer, serial)
        self._factsheet = factsheet
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._report = Report(self._lock, self._wake.set)
        self._driving = Driving(self._lock, self._report, robot, runs, store, self._active_map)
        charging = Charging(robot, self._report) if getattr(robot, "docking", None) is not None else None
        self._instant = InstantActions(self._driving, self._report, modes, self._active_map, self._state_due,
                                       self._send_factsheet, charging)
        self._last_state, self._last_sent = None, 0.0
        self._last_pose, self._last_shown = None, 0.0
        self._position_read, self._read_at = None, None  # agvPosition, read at most once a second unless sent
        self._busy = True
        self._oversize = Throttled(log, "VDA 5050 oversize state lines", burst=3)
        self._closing = threading.Event()
        self._thread = None
        link.set_will(self.topic("connection"), self._connection("CONNECTIONBROKEN"))
        link.say_on_close(self.topic("connection"), lambda: self._connection("OFFLINE"))
        for name, take in (("order", self._on_order), ("instantActions", self._on_instant_actions)):
            link.handle(self.topic(name), take, max_payload=messages.MAX_PAYLOAD,
                        too_big=lambda size, name=name: self._too_big(name, size))
        link.when_connected(self._connected)
        robot.estop.when_engaged(lambda _source: self._wake.set())

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

    # in ----------------------------------------------------------------------

    def _on_order(self, text):
        try:
            order = check(_parsed(text))
            self._addressed(order, "order")
            unsupported(order)
            self._driving.take(order)
        except Refusal as refusal:
            self._report.refuse(refusal)
        self._wake.set()

    def _on_instant_actions(self, text):
        try:
            self._instant.take(_parsed(text), addressed=lambda message: self._addressed(message, "instantActions"))
        except Refusal as refusal:
            self._report.refuse(refusal, "instantActions")

    def _addressed(self, message, what):
        """Refusal (validationError) for a message whose header names another vehicle: a master's mix-up, or a
        client publishing where it should not; the other's names are not repeated."""
        ours = self._headers.identity()
        theirs = (message.get("manufacturer"), message.get("serialNumber"))
        if theirs != ours:
            raise Refusal("validationError", "This {} is addressed to another vehicle (its header's manufacturer "
                          "and serialNumber); this one is {}/{}: nothing was done.".format(what, *ours),
                          [("serialNumber", ours[1])])

    def _too_big(self, topic, size):
        self._report.refuse(Refusal("validationError", "A message of {} bytes on {} is larger than the {} bytes "
                                    "this robot takes.".format(size, topic, messages.MAX_PAYLOAD),
                                    [("topic", topic)]), topic)

    def _active_map(self):
        """The mapId of the map the robot navigates on (a named map, or the stack's own), or None."""
        if self._modes is None:
            return self._own_map
        status = self._modes.status()
        if status["mode"] != "navigation":
            return None
        return status["map"] or self._own_map

    # out ---------------------------------------------------------------------

    def _connection(self, state):
        return self._json("connection", messages.connection(state))

    def _json(self, topic, body):
        return json.dumps(self._headers.stamp(topic, body), ensure_ascii=False)

    def _connected(self):
        """After each connect (paho's thread): ONLINE, the factsheet, the state."""
        self._link.publish(self.topic("connection"), self._connection("ONLINE"), retain=True)
        self._send_factsheet()
        self._state_due()

    def _send_factsheet(self):
        self._link.publish(self.topic("factsheet"), self._json("factsheet", self._factsheet), retain=True, qos=0)

    def _state_due(self):
        """The next look sends the state whatever changed (a connect, a stateRequest)."""
        self._last_state = None
        self._wake.set()

    def _loop(self):
        while not self._closing.is_set():
            self._wake.wait(LOOK_EVERY if self._busy else IDLE_LOOK_EVERY)
            self._wake.clear()
            if self._closing.is_set():
                return
            try:
                self._driving.look()
                self._tell()
            except Exception:  # a bug in one look must not end the fleet manager's view of the robot
                log.exception("VDA 5050: could not build the state")

    def _tell(self):
        """The state when it changed (or STATE_EVERY passed); the pose on visualization when it moved."""
        body = self.state_body()
        now = self._clock()
        self._busy = bool(body["nodeStates"] or body["edgeStates"] or body["driving"])
        position = self._position_at(now)
        trigger = {k: v for k, v in body.items() if k not in RIDE_ALONG}
        trigger["agvPosition"] = position and (position["mapId"], position["positionInitialized"])  # known or not
        if trigger != self._last_state or now - self._last_sent >= STATE_EVERY:
            position = self._position_at(now, fresh=True)
            self._last_state, self._last_sent = trigger, now
            sent = dict(body, agvPosition=position) if position is not None else body
            self._link.publish(self.topic("state"), self._json("state", self._within_ceiling(sent)), qos=0)
        if position is not None and position != self._last_pose and now - self._last_shown >= VISUALIZATION_EVERY:
            self._last_pose, self._last_shown = position, now
            self._link.publish(self.topic("visualization"), self._json("visualization", {"agvPosition": position}),
                               qos=0)

    def _within_ceiling(self, body):
        """``body``, or it without its action states (then its errors) when it is over MAX_STATE bytes."""
        for leave_out in ((), ("actionStates",), ("actionStates", "errors")):
            smaller = dict(body, **{key: [] for key in leave_out})
            size = len(json.dumps(smaller, ensure_ascii=False).encode("utf-8"))
            if size <= messages.MAX_STATE:
                if leave_out:
                    self._oversize.log(logging.WARNING, "VDA 5050: a state of %d bytes is over %d: sent without "
                                       "its %s", size, messages.MAX_STATE, " and ".join(leave_out))
                return smaller
        return smaller

    def _position_at(self, now, fresh=False):
        """agvPosition, read again when ``fresh`` or a second old (a tf lookup is most of a look's cost)."""
        if fresh or self._read_at is None or now - self._read_at >= VISUALIZATION_EVERY:
            if not (fresh and self._read_at == now):
                self._position_read, self._read_at = self._position(), now
        return self._position_read

    def state_body(self):
        """The state without its header and agvPosition."""
        robot = self._robot
        nav, estop = robot.navigation_status(), robot.estop_status()
        battery, information = _battery(robot.battery_status())
        run_paused = self._driving.run_paused()
        with self._lock:
            book = self._driving.book
            errors, actions = self._report.snapshot()
            body = {
                "orderId": book.order_id, "orderUpdateId": book.update_id,
                "lastNodeId": book.last_node_id, "lastNodeSequenceId": book.last_node_seq,
                "nodeStates": book.node_states(), "edgeStates": book.edge_states(),
                "actionStates": actions, "errors": errors, "paused": self._driving.paused or run_paused,
            }
        stuck = robot.stuck_status()
        if stuck is not None and stuck["state"] != "free":
            body["errors"].append(stuck_error(stuck, book.order_id))
        # Read again after the order: a stop that came meanwhile (and dropped the order) is not "driving".
        nav, teleop = robot.navigation_status() if nav.get("state") == "active" else nav, robot.teleop_control.status()
        body.update({
            "driving": nav.get("state") == "active" or bool(teleop.get("active")),
            "newBaseRequest": False,
            "operatingMode": "MANUAL" if teleop.get("active") and teleop.get("by") == "owner" else "AUTOMATIC",
            "loads": [], "batteryState": battery, "information": information,
            "safetyState": {"eStop": ESTOP_TYPES.get(estop["source"], "REMOTE") if estop["latched"] else "NONE",
                            "fieldViolation": False},
        })
        return body

    def _position(self):
        """``agvPosition`` from the pose tracker, or None while the pose is unknown."""
        tracker = self._robot.pose
        reading = tracker.current() if self._robot.node.connected else None
        if reading is None:
            return None
        fresh = tracker.age(reading) <= tracker.max_age
        map_id = self._active_map()
        position = {"x": round(reading.pose.x, 3), "y": round(reading.pose.y, 3),
                    "theta": _angle(reading.pose.yaw), "mapId": map_id or "",
                    "positionInitialized": fresh and map_id is not None}
        spread = tracker.amcl_spread
        if spread is not None:
            position["localizationScore"] = round(max(0.0, 1.0 - math.hypot(spread[0], spread[1])
                                                      / SPREAD_FOR_NO_SCORE), 3)
        return position


def stuck_error(stuck, order_id):
    """The error a stuck robot shows while it is (``/status`` ``stuck``): WARNING while it backs out by
    itself, FATAL while it waits for someone to free it (the standard's "user intervention required").
    The order is not finished: its nodes stay, and resuming it goes on."""
    error = {"errorType": "stuck", "errorLevel": "WARNING" if stuck["state"] == "backing_out" else "FATAL",
             "errorDescription": (stuck.get("message") or "The robot is stuck.")[:200]}
    if order_id:
        error["errorReferences"] = [{"referenceKey": "orderId", "referenceValue": str(order_id)}]
    return error


def _angle(yaw):
    """``yaw`` to 4 places, within [-pi, pi] as the schema says (rounding 3.14159 up would leave it)."""
    return max(-math.pi, min(math.pi, round(math.atan2(math.sin(yaw), math.cos(yaw)), 4)))


def _parsed(text):
    try:
        return json.loads(text)
    except ValueError as exc:
        raise Refusal("validationError", "Not JSON: {}".format(exc))
    except RecursionError:  # "[[[[…" nested deeper than Python's JSON reader goes
        raise Refusal("validationError", "Not JSON this robot reads: nested too deep.")


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
