"""Home Assistant's event entities: a goal's end and a run's end, each told once, as it happens.

``<root>/event/arrival``: ``{"event_type": "arrived" | "failed", "place", "message"}`` (``place``:
the waypoint's name, None for a goal to x, y); ``<root>/event/run``: ``{"event_type": "succeeded" |
"failed" | "canceled" | "skipped", "id", "route", "message"}``. From the robot's happenings
(``core/happenings.py``: no exploring's or docking's own goals). Not retained: an event is told
when it happens, never replayed to a Home Assistant that connects later. Home Assistant shows them
as the ``event`` entities Arrival and Run ended (``home_assistant.py``): a second arrival at the
same place is a new event, where the Last reached sensor would not change. Pure: no paho.
"""

import json

from flask_move_server.core.happenings import ARRIVED, FAILED, RUN_DONE
from flask_move_server.missions.history import ENDED as RUN_TYPES

ARRIVAL_TYPES = (ARRIVED, FAILED)


def arrival_topic(root):
    return root + "/event/arrival"


def run_topic(root):
    return root + "/event/run"


class HaEvents:
    """Publishes each arrival, failed goal and run's end on ``link`` as Home Assistant's events."""

    def __init__(self, link, happenings):
        self._link = link
        happenings.listen(self._happened)

    def _happened(self, name, data):
        """A happening (in its own thread: the link only queues, never blocks)."""
        if name in (ARRIVED, FAILED):
            topic = arrival_topic(self._link.root)
            told = {"event_type": name, "place": data.get("target"), "message": data.get("message")}
        elif name == RUN_DONE and data.get("state") in RUN_TYPES:
            topic = run_topic(self._link.root)
            told = {"event_type": data["state"], "id": data.get("id"), "route": data.get("route"),
                    "message": data.get("message")}
        else:
            return
        self._link.publish(topic, json.dumps(told, ensure_ascii=False), retain=False)
