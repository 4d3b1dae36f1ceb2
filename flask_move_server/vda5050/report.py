"""What the state tells besides the order: ``errors`` and ``actionStates`` (VDA 5050 2.0.0, 6.10.5, 6.11).

A refused order's warning stays until an order is taken (section 6.6.4); both lists are bounded,
and identical refusals are told once. Shares the vehicle's lock, so that one state shows an
action's end together with what it changed (a ``cancelOrder`` FINISHED and the order dropped).
"""

import logging

from flask_move_server.process.log_limits import Throttled

log = logging.getLogger(__name__)

KEPT_ERRORS = 10
KEPT_ACTION_STATES = 50


class Report:
    """``lock``: the vehicle's (held by the state when it reads); ``wake()``: the state is due."""

    def __init__(self, lock, wake):
        self._lock, self._wake = lock, wake
        self._errors, self._actions = [], []
        self._lines = Throttled(log, "VDA 5050 refusal lines", burst=10)

    def refuse(self, refusal, what="order"):
        """``refusal`` (an order.Refusal) shown as a WARNING until an order is taken."""
        self._lines.log(logging.WARNING, "VDA 5050: %s refused (%s): %s", what, refusal.error_type, refusal)
        self.add_error(refusal.as_error())

    def add_error(self, error):
        with self._lock:
            self.note_error(error)

    def note_error(self, error):
        """Lock held: ``error`` shown (an identical one is told once); the state is due."""
        same = (error["errorType"], error["errorDescription"])
        kept = [e for e in self._errors if (e["errorType"], e["errorDescription"]) != same]
        self._errors = (kept + [error])[-KEPT_ERRORS:]
        self._wake()

    def order_taken(self, new):
        """Lock held: an order was taken: its warnings go; a new order's action states go too (Figure 8)."""
        self._errors = []
        if new:
            self._actions = []

    def action(self, action, status, result=None, then=None):
        """``action`` (an instant action) is ``status`` now; ``then()`` runs under the same lock."""
        state = {"actionId": action["actionId"], "actionType": action["actionType"], "actionStatus": status}
        if result:
            state["resultDescription"] = str(result)[:200]
        with self._lock:
            kept = [a for a in self._actions if a["actionId"] != action["actionId"]]
            self._actions = (kept + [state])[-KEPT_ACTION_STATES:]
            if then is not None:
                then()
        self._wake()

    def snapshot(self):
        """Lock held: ``(errors, actionStates)`` as the state sends them."""
        return [dict(e) for e in self._errors], [dict(a) for a in self._actions]
