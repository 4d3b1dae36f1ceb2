"""A fleet manager's instant actions (VDA 5050 2.0.0, section 6.9), each reported in ``actionStates``.

``cancelOrder`` (``noOrderToCancel`` without an order), ``startPause`` / ``stopPause``,
``initPosition`` (relocalize on the active map), ``stateRequest``, ``factsheetRequest``,
``startCharging`` / ``stopCharging`` (dock and undock: charging.py). Another
action type FAILS, saying so. One action failing never keeps the next of the message from its turn.
Every text the state may echo (ids, types, ``mapId``, ``lastNodeId``) is at most ``MAX_ID``
characters, as the factsheet's ``idLen`` says, or the message is refused without echoing it: 60
messages of 255 KB ids made each state 17 MB and stalled the robot (issue 34).
"""

import logging

from flask_move_server.core.errors import MoveServerError
from flask_move_server.core.geometry import Pose2D
from flask_move_server.vda5050.charging import REPORTED  # an action that reported its own end
from flask_move_server.vda5050.messages import MAX_ACTIONS
from flask_move_server.vda5050.order import HEADER, MAX_ID, Refusal, finite

log = logging.getLogger(__name__)

FINISHED, FAILED = "FINISHED", "FAILED"


class InstantActions:
    """``driving`` the order's (driving.py), ``report`` the vehicle's; ``modes`` the mode manager (None:
    localization is someone else's); ``active_map()``; ``tell_state()``, ``tell_factsheet()`` send now."""

    def __init__(self, driving, report, modes, active_map, tell_state, tell_factsheet, charging=None):
        self._driving, self._report, self._modes, self._active_map = driving, report, modes, active_map
        self._acts = {"cancelOrder": self._cancel_order, "startPause": self._start_pause,
                      "stopPause": self._stop_pause, "initPosition": self._init_position,
                      "stateRequest": lambda action: tell_state() or "Sent.",
                      "factsheetRequest": lambda action: tell_factsheet() or "Sent."}
        if charging is not None:
            self._acts.update(startCharging=charging.start, stopCharging=charging.stop)

    def take(self, message, addressed=None):
        """Each action of ``message`` (parsed JSON), in order; Refusal (validationError) for the message.
        ``addressed(message)`` refuses one whose header names another vehicle."""
        actions = _actions(message)
        if addressed is not None:
            addressed(message)
        for action in actions:
            self._act(action)

    def _act(self, action):
        act = self._acts.get(action["actionType"])
        if act is None:
            self._report.action(action, FAILED, "This robot does not do {}.".format(action["actionType"]))
            self._report.refuse(Refusal("orderError", "Instant action {} is not one this robot does (its factsheet "
                                        "lists them).".format(action["actionType"]),
                                        [("actionId", action["actionId"]), ("actionType", action["actionType"])]),
                                action["actionType"])
            return
        try:
            result = act(action)
        except (MoveServerError, Refusal) as exc:
            self._report.action(action, FAILED, str(exc))
            if isinstance(exc, Refusal):
                self._report.refuse(exc, action["actionType"])
            return
        except Exception:  # a bug in one action must not keep the next from its turn
            log.exception("VDA 5050: instant action %s failed", action["actionType"])
            self._report.action(action, FAILED, "The robot could not do it (its log says why).")
            return
        if result is not REPORTED:
            self._report.action(action, FINISHED, result)

    def _cancel_order(self, action):
        self._driving.cancel(action, self._report)
        return REPORTED

    def _start_pause(self, _action):
        self._driving.pause()
        return "Paused."

    def _stop_pause(self, _action):
        self._driving.resume()
        return "Driving on."

    def _init_position(self, action):
        params = {p.get("key"): p.get("value") for p in action.get("actionParameters", []) if isinstance(p, dict)}
        for key in ("x", "y", "theta"):
            value = params.get(key)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not finite(value):
                raise Refusal("validationError", "initPosition needs a number '{}'.".format(key),
                              [("actionId", action["actionId"])])
        for key in ("mapId", "lastNodeId"):
            value = params.get(key)
            if value is not None and (not isinstance(value, str) or len(value) > MAX_ID):
                raise Refusal("validationError", "initPosition's '{}' is a text of at most {} characters.".format(
                    key, MAX_ID), [("actionId", action["actionId"])])
        active = self._active_map()
        if params.get("mapId") != active:
            raise MoveServerError("mapId {!r} is not the map the robot navigates on ({}).".format(
                params.get("mapId"), active or "none"))
        if self._modes is None:
            raise MoveServerError("This server does not run localization; set the pose in RViz.")
        self._modes.set_pose(Pose2D(float(params["x"]), float(params["y"]), float(params["theta"])))
        if isinstance(params.get("lastNodeId"), str):
            self._driving.at_node(params["lastNodeId"])
        return "Localization set."


def _actions(message):
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
    if len(message["actions"]) > MAX_ACTIONS:
        raise Refusal("validationError", "instantActions holds {} actions; at most {} are taken.".format(
            len(message["actions"]), MAX_ACTIONS))
    for action in message["actions"]:
        if not isinstance(action, dict) or not all(isinstance(action.get(k), str)
                                                   for k in ("actionId", "actionType", "blockingType")):
            raise Refusal("validationError", "Each instant action has text 'actionId', 'actionType' and "
                          "'blockingType'.")
        long = next((k for k in ("actionId", "actionType", "blockingType") if len(action[k]) > MAX_ID), None)
        if long is not None:
            raise Refusal("validationError", "An instant action's '{}' is longer than {} characters.".format(
                long, MAX_ID))
        if not isinstance(action.get("actionParameters", []), list):
            raise Refusal("validationError", "actionParameters of {} is a list.".format(action["actionId"]),
                          [("actionId", action["actionId"])])
    return message["actions"]
