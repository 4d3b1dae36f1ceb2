"""The reporter: what the robot is doing, told on the event bus as it changes.

One thread samples the Robot facade (``robot.status()``) ``rate`` times a second and
publishes, on the :class:`~flask_move_server.core.events.EventBus`:

- ``pose`` (``{"x", "y", "yaw", "frame", "age", "source"}`` as ``/status`` shows it, or None)
  when the robot moved (1 mm or 0.001 rad), when it became known or unknown, and once a
  second at rest (so a page sees the pose's ``age`` grow when localization stops);
- ``status`` (``{"navigation", "teleop", "motors", "ros"}``) when any of it changed,
  ignoring the fields that tick by themselves (teleop ``remaining``, motors ``command_age``,
  odometry) and the distance left below 5 cm;
- ``estop`` (the ``/status`` estop dict) when the latch changed; an engage is also told at
  once from the latch's own callback, not 100 ms later;
- ``battery`` (the ``/status`` battery dict) once a reading came (never while none did: a robot
  without a fuel gauge has no battery event), then when the percentage moved 1 point or more
  from the one told, charging changed, the voltage moved 0.1 V (only when there is no
  percentage: a voltage monitor's robot), or the reading became ``BATTERY_OLD`` seconds old (its
  publisher stopped); never for its ``age`` ticking.

Sampling instead of hooking every part keeps the parts unaware of the bus, and costs one
``robot.status()`` per tick (a tf lookup and a few locks; docs/performance.md has the CPU).
Only while someone reads the events: with no subscription the thread sleeps, and a new
subscriber's first sample is taken in its own thread before its stream is primed, so what it
is shown first is the robot now, not when the last page closed.
Pure: imports neither rospy nor Flask; what it calls may.
"""

import logging
import threading
import time

log = logging.getLogger(__name__)

RATE = 10.0  # samples a second: the page draws the robot at this rate while it moves
POSE_REFRESH = 1.0  # s: a pose at rest is told again this often, its age updated
MOVED = 0.001  # m and rad: a smaller change of pose is not news
DISTANCE_STEP = 0.05  # m: distance_remaining changes smaller than this are not news
PERCENT_STEP = 1.0  # battery percentage points: a smaller change is not news
VOLTAGE_STEP = 0.1  # V: nor this, when the battery tells no percentage
BATTERY_OLD = 30.0  # s: a battery reading this old is told once more (the page greys it: its publisher stopped)

# Fields that change on every sample without anything happening: left out of the comparison.
_TICKING = {"teleop": ("remaining",), "motors": ("command_age", "odom")}
STATUS_PARTS = ("navigation", "teleop", "motors", "ros")


class Reporter:
    """Samples ``robot`` in a thread and publishes what changed on ``events``."""

    def __init__(self, robot, events, rate=RATE, clock=time.monotonic):
        self._robot = robot
        self._events = events
        self._period = 1.0 / rate
        self._clock = clock
        self._last = {"pose": None, "status": None, "estop": None, "battery": None}
        self._pose_told_at = None
        self._lock = threading.Lock()  # one sample at a time
        self._estop_lock = threading.Lock()  # the e-stop read and told in one step (thread and callback)
        self._stop = threading.Event()
        self._reader_came = threading.Event()  # wakes the thread sleeping while nobody reads
        self._thread = None
        estop = getattr(robot, "estop", None)
        if estop is not None:
            estop.when_engaged(lambda source: self._tell_estop())
        events.when_subscribed(self._bring_up_to_date)

    def start(self):
        """Start sampling (a daemon thread); returns self."""
        if self._thread is None and not self._stop.is_set():
            self._thread = threading.Thread(target=self._run, name="event-reporter", daemon=True)
            self._thread.start()
        return self

    def _run(self):
        failing = False
        while not self._stop.is_set():
            if not self._events.subscribers:
                self._reader_came.wait()  # nobody reads: nothing to tell until a subscriber (or close) wakes us
                self._reader_came.clear()
                continue
            if self._stop.wait(self._period):
                return
            try:
                self.sample()
            except Exception:  # a part's bug must not end the page's live view, nor flood the log
                if not failing:
                    log.exception("sampling the robot for events failed (logged once until it works again)")
                failing = True
            else:
                if failing:
                    log.info("sampling the robot for events works again")
                failing = False

    def _bring_up_to_date(self):
        """A new subscriber (in its thread, before its stream is primed): sample now, and wake the thread."""
        self._reader_came.set()
        if not self._stop.is_set():
            self.sample()

    def sample(self):
        """Read the robot once and publish what changed since the last sample."""
        with self._lock:  # read and told as one step: a sample never tells an older reading after a newer one
            status = self._robot.status()
            self._tell_pose(status.get("pose"))
            self._tell_status({part: status.get(part) for part in STATUS_PARTS})
            self._tell_battery(status.get("battery"))
        self._tell_estop()

    def _tell_pose(self, pose):
        now = self._clock()
        last = self._last["pose"]
        due = self._pose_told_at is None or now - self._pose_told_at >= POSE_REFRESH
        if pose_moved(last, pose) or (pose is not None and due):
            self._last["pose"] = pose
            self._pose_told_at = now
            self._events.publish("pose", pose)

    def _tell_status(self, status):
        key = status_key(status)
        if key != self._last["status"]:
            self._last["status"] = key
            self._events.publish("status", status)

    def _tell_battery(self, battery):
        if battery_news(self._last["battery"], battery):
            self._last["battery"] = battery
            self._events.publish("battery", battery)

    def _tell_estop(self):
        """Read the latch and tell it if it changed, as one step: a sample's older reading can never
        be told after the engage callback's newer one (a page would see 'released' for a moment)."""
        with self._estop_lock:
            estop = self._robot.estop_status()
            if estop != self._last["estop"]:
                self._last["estop"] = estop
                self._events.publish("estop", estop)

    def close(self):
        """Stop sampling. Idempotent."""
        self._stop.set()
        self._reader_came.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2)


def pose_moved(before, after):
    """True when ``after`` is news compared with ``before`` (known/unknown, frame, or moved)."""
    if before is None or after is None:
        return before is not after
    if before.get("frame") != after.get("frame"):
        return True
    return any(abs(after[k] - before[k]) >= MOVED for k in ("x", "y", "yaw"))


def battery_news(before, after):
    """True when the battery reading ``after`` is news compared with the one told, ``before``."""
    if before is None or after is None:
        return before is not after
    if before.get("charging") != after.get("charging"):
        return True
    if _old(before) != _old(after):
        return True
    return (_moved(before.get("percentage"), after.get("percentage"), PERCENT_STEP)
            or (after.get("percentage") is None
                and _moved(before.get("voltage"), after.get("voltage"), VOLTAGE_STEP)))


def _old(battery):
    return (battery.get("age") or 0.0) >= BATTERY_OLD


def _moved(before, after, step):
    if before is None or after is None:
        return before is not after
    return abs(after - before) >= step - 1e-9


def status_key(status):
    """``status`` without the fields that tick by themselves: equal keys mean nothing happened."""
    key = {}
    for part, data in status.items():
        if isinstance(data, dict):
            data = {k: v for k, v in data.items() if k not in _TICKING.get(part, ())}
            if data.get("distance_remaining") is not None:
                data["distance_remaining"] = round(data["distance_remaining"] / DISTANCE_STEP)
        key[part] = data
    return key
