"""What the state tells besides the order: ``errors`` and ``actionStates`` (VDA 5050 2.0.0, 6.10.5, 6.11).

A refused order's warning stays until an order is taken (section 6.6.4); both lists are bounded
in count and in bytes, each text in them cut to its length, and identical refusals are told once.
Shares the vehicle's lock, so that one state shows an action's end together with what it changed
(a ``cancelOrder`` FINISHED and the order dropped).
"""

import json
import logging

from flask_move_server.process.log_limits import Throttled
from flask_move_server.vda5050.order import MAX_ID

log = logging.getLogger(__name__)

KEPT_ERRORS = 10
KEPT_ACTION_STATES = 50
KEPT_ERROR_BYTES = 16 * 1024  # of the errors kept, as the state's JSON (UTF-8) holds them
KEPT_ACTION_BYTES = 48 * 1024  # of the action states kept
MAX_DESCRIPTION = 500  # characters of an errorDescription
MAX_RESULT = 200  # characters of a resultDescription
MAX_REFERENCES = 5  # errorReferences of one error


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
        error = _bounded_error(error)
        same = (error["errorType"], error["errorDescription"])
        kept = [e for e in self._errors if (e[1]["errorType"], e[1]["errorDescription"]) != same]
        self._errors = _newest(kept + [_sized(error)], KEPT_ERRORS, KEPT_ERROR_BYTES)
        self._wake()

    def order_taken(self, new):
        """Lock held: an order was taken: its warnings go; a new order's action states go too (Figure 8)."""
        self._errors = []
        if new:
            self._actions = []

    def action(self, action, status, result=None, then=None):
        """``action`` (an instant action) is ``status`` now; ``then()`` runs under the same lock."""
        state = {"actionId": _cut(action["actionId"], MAX_ID), "actionType": _cut(action["actionType"], MAX_ID),
                 "actionStatus": status}
        if result:
            state["resultDescription"] = _cut(result, MAX_RESULT)
        with self._lock:
            kept = [a for a in self._actions if a[1]["actionId"] != state["actionId"]]
            self._actions = _newest(kept + [_sized(state)], KEPT_ACTION_STATES, KEPT_ACTION_BYTES)
            if then is not None:
                then()
        self._wake()

    def snapshot(self):
        """Lock held: ``(errors, actionStates)`` as the state sends them."""
        return [dict(e) for _, e in self._errors], [dict(a) for _, a in self._actions]


def _cut(text, length):
    text = str(text)
    return text if len(text) <= length else text[:length - 1] + "…"


def _bounded_error(error):
    """``error`` with its texts cut and at most MAX_REFERENCES references."""
    return dict(error, errorDescription=_cut(error["errorDescription"], MAX_DESCRIPTION), errorReferences=[
        {"referenceKey": _cut(r["referenceKey"], MAX_ID), "referenceValue": _cut(r["referenceValue"], MAX_ID)}
        for r in error.get("errorReferences", [])[:MAX_REFERENCES]])


def _sized(entry):
    """``(bytes, entry)``: what ``entry`` takes in the state's JSON (UTF-8), and it."""
    return len(json.dumps(entry, ensure_ascii=False).encode("utf-8")) + 1, entry


def _newest(entries, count, budget):
    """The newest of ``entries`` (``_sized``, oldest first): at most ``count`` of them, ``budget`` bytes."""
    kept, size = [], 0
    for entry in reversed(entries[-count:]):
        size += entry[0]
        if size > budget:
            break
        kept.append(entry)
    return kept[::-1]
