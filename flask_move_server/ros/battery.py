"""The battery's charge from ``sensor_msgs/BatteryState`` (``battery.topic``), when something publishes it.

The seed robot has no fuel gauge: nothing publishes, and ``status()`` stays None (the page shows no
battery, ``/status`` says ``"battery": null``). A robot with one (a BMS driver, a voltage monitor,
the simulated robot) publishes ``BatteryState`` and ``/status`` tells the latest reading:

- ``percentage``: 0-100, to 0.1 (the message's 0..1); None when it says NaN (unknown, as a voltage
  monitor without a charge model publishes) or a value outside 0..1 (a driver sending 0..100 by
  mistake: not guessed at, said once in the log);
- ``voltage``: V, to 0.01; None for NaN, infinity, zero or less;
- ``charging``: True while ``power_supply_status`` is CHARGING; False when DISCHARGING,
  NOT_CHARGING or FULL (a full battery on its charger is not charging: the percentage says it is
  full); None when UNKNOWN (the message's default) or anything else;
- ``age``: seconds since the reading arrived (on this machine's clock: a publisher's stamp may be
  zero or from another clock). An old reading is kept: the age tells that the publisher stopped.

``present`` is not read: most publishers leave it at its default (False) whatever the battery.
"""

import logging
import math
import threading
import time

import rospy
from sensor_msgs.msg import BatteryState

log = logging.getLogger(__name__)

# sensor_msgs/BatteryState power_supply_status
CHARGING, DISCHARGING, NOT_CHARGING, FULL = 1, 2, 3, 4
CHARGING_STATES = {CHARGING: True, DISCHARGING: False, NOT_CHARGING: False, FULL: False}
SUPPLY = {CHARGING: "charging", FULL: "full", DISCHARGING: "off", NOT_CHARGING: "off"}  # for docking
SLACK = 0.005  # a percentage this far outside 0..1 is float rounding, clamped; farther is nonsense


class BatteryMonitor:
    """The latest ``sensor_msgs/BatteryState`` on ``topic``, kept thread-safely."""

    def __init__(self, topic, node, clock=time.monotonic):
        self.topic = topic
        self._clock = clock
        self._lock = threading.Lock()
        self._reading = None  # (percentage, voltage, charging, monotonic time heard, supply)
        self._warned = set()  # the kinds of bad value already logged
        self._subscriber = None
        self._closed = False
        node.when_ready(self._setup, part="BatteryMonitor")

    def _setup(self):
        if self._closed:
            return
        self._subscriber = rospy.Subscriber(self.topic, BatteryState, self._on_message, queue_size=1)

    def _on_message(self, msg):
        reading = (self._percentage(msg.percentage), self._voltage(msg.voltage),
                   CHARGING_STATES.get(msg.power_supply_status), self._clock(), SUPPLY.get(msg.power_supply_status))
        with self._lock:
            self._reading = reading

    def status(self):
        """``{"percentage", "voltage", "charging", "age"}`` of the latest reading, or None when none came."""
        with self._lock:
            reading = self._reading
        if reading is None:
            return None
        percentage, voltage, charging, heard, _ = reading
        return {"percentage": percentage, "voltage": voltage, "charging": charging,
                "age": round(max(0.0, self._clock() - heard), 1)}

    def supply(self, max_age):
        """What the latest reading says of the charger: ``"charging"`` (CHARGING), ``"full"`` (FULL), ``"off"``
        (DISCHARGING, NOT_CHARGING), or None (UNKNOWN, no reading, or one older than ``max_age`` s)."""
        with self._lock:
            reading = self._reading
        if reading is None or self._clock() - reading[3] > max_age:
            return None
        return reading[4]

    def _percentage(self, value):
        if not _finite(value):
            return None  # NaN: the publisher does not know the charge
        if not -SLACK <= value <= 1.0 + SLACK:
            self._warn_once("percentage", "battery: %s says percentage %r, outside 0..1 (a driver sending "
                            "0..100?): shown as unknown", self.topic, value)
            return None
        return round(min(1.0, max(0.0, value)) * 100.0, 1)

    def _voltage(self, value):
        if not _finite(value) or value <= 0.0:  # 0: the default of a publisher that does not measure it
            if _finite(value) and value < 0.0:
                self._warn_once("voltage", "battery: %s says voltage %r: shown as unknown", self.topic, value)
            return None
        return round(value, 2)

    def _warn_once(self, kind, message, *args):
        if kind not in self._warned:
            self._warned.add(kind)
            log.warning(message, *args)

    def close(self):
        """Stop listening. Idempotent."""
        self._closed = True
        subscriber, self._subscriber = self._subscriber, None
        if subscriber is not None:
            subscriber.unregister()


def _finite(value):
    try:
        return math.isfinite(value)
    except TypeError:
        return False
