"""The simulated robot's battery: drains while the wheels turn, charges on the dock, told as ROS tells it.

``BatteryModel`` (pure) keeps the charge, 0..1. Each step of simulated time it loses
``REST_DRAIN`` a second (the Pi, the lidar) plus ``DRIVE_DRAIN`` per metre the wheels roll (their
mean ground speed, so a turn on the spot costs too), and gains ``CHARGE_RATE`` a second instead
while the robot stands (wheels still) with its contacts on the charger's, up to full.
At the robot's cruise speed (0.3 m/s) that is about 2 % a minute: 100 % to 60 % in 20 minutes of
driving, and +1 % every 10 s on the dock, so the demo shows a change within minutes.

``SimBattery`` (the ROS side) steps the model on the world's clock (``sim/clock.py``:
``sim.speed_factor`` times real time while the world keeps up, slower on a loaded machine, as the
robot moves) and publishes ``sensor_msgs/BatteryState`` on ``battery.topic`` at ``RATE``:
percentage 0..1, a 3-cell Li-ion voltage that follows the charge, and
``power_supply_status`` CHARGING on the dock, FULL on the dock at 100 %, DISCHARGING elsewhere.

Where the dock is comes from a callable the server gives (the active map's dock, the waypoint
marked as the charger, in the map frame: the simulated world's frame on maps drawn true or built
by the simulated SLAM). The charger is as strict as a real one (:func:`on_contacts`): the robot's
*true* pose, not what localization believes, must stand on the dock's pose within a few
centimetres sideways and a few degrees of yaw, touching (``CONTACTS``); a sloppy approach, or one
on a wrong belief, does not charge.
"""

import logging
import threading
import time

import rospy
from sensor_msgs.msg import BatteryState

from flask_move_server.core.geometry import compose, inverse, normalize_angle

log = logging.getLogger(__name__)

START = 0.87  # the charge the simulated robot starts with (sim.battery_start)
REST_DRAIN = 0.002 / 60.0  # a second, standing: 0.2 % a minute
DRIVE_DRAIN = 0.001  # a metre the wheels roll: 1 % every 10 m
CHARGE_RATE = 0.001  # a second on the dock: 1 % every 10 s
CONTACTS = (-0.03, 0.05, 0.04, 0.09)  # the charger's contacts touch the robot's: m along the dock's line
# from (before it) and to (the sim has no charger's body to stop the robot: driven on past the dock, a
# real robot would stand pressed on it, its sprung contacts touching), m sideways either way, rad of yaw
STILL = 0.005  # m/s: wheels slower than this stand still
CELLS = 3
CELL_EMPTY, CELL_FULL = 3.3, 4.2  # V a cell, at 0 % and 100 %
RATE = 1.0  # BatteryState messages a second
STEP = 0.1  # s of real time between model steps (the wheels' speed is sampled this often)


class BatteryModel:
    """The charge of the simulated battery, 0..1, stepped by what the robot does. Pure, not thread-safe."""

    def __init__(self, charge=START):
        self.charge = min(1.0, max(0.0, charge))
        self.charging = False

    def step(self, dt, wheel_speed, on_dock):
        """``dt`` s of simulated time at mean wheel ground speed ``wheel_speed`` (m/s); returns the charge."""
        self.charging = on_dock and abs(wheel_speed) < STILL
        if self.charging:
            self.charge = min(1.0, self.charge + CHARGE_RATE * dt)
        else:
            self.charge = max(0.0, self.charge - (REST_DRAIN + DRIVE_DRAIN * abs(wheel_speed)) * dt)
        return self.charge

    @property
    def status(self):
        """``power_supply_status``: CHARGING or FULL on the dock, DISCHARGING elsewhere."""
        if not self.charging:
            return BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        return BatteryState.POWER_SUPPLY_STATUS_FULL if self.charge >= 1.0 else \
            BatteryState.POWER_SUPPLY_STATUS_CHARGING

    @property
    def voltage(self):
        return CELLS * (CELL_EMPTY + (CELL_FULL - CELL_EMPTY) * self.charge)


def on_contacts(dock, pose):
    """True when the robot at ``pose`` (its true pose) touches the charger at ``dock`` (a Pose2D)."""
    off = compose(inverse(dock), pose)
    behind, past, sideways, turned = CONTACTS
    return behind <= off.x <= past and abs(off.y) <= sideways and abs(normalize_angle(off.yaw)) <= turned


class SimBattery:
    """Steps a :class:`BatteryModel` in a thread and publishes it as ``sensor_msgs/BatteryState``."""

    def __init__(self, topic, node, wheel_speeds, pose, dock, clock, model=None):
        """``wheel_speeds()``: (left, right) m/s; ``pose()``: the robot's true Pose2D; ``dock()``: the
        dock's Pose2D in the same frame, or None when there is none; ``clock()``: the world's simulated
        seconds (``SimWorld.clock.now``), so the battery drains as the world advances, not as real time does."""
        self.topic = topic
        self.model = model or BatteryModel()
        self._wheel_speeds = wheel_speeds
        self._pose = pose
        self._dock = dock
        self._clock = clock
        self._publisher = None
        self._thread = None
        self._stop = threading.Event()
        self._dock_failed = False
        node.when_ready(self._setup, part="SimBattery")

    def _setup(self):
        if self._stop.is_set():
            return
        self._publisher = rospy.Publisher(self.topic, BatteryState, queue_size=1)
        self._thread = threading.Thread(target=self._run, name="sim-battery", daemon=True)
        self._thread.start()
        log.info("simulated battery at %.0f %% on %s", self.model.charge * 100, self.topic)

    def _run(self):
        next_message = time.monotonic()
        last = self._clock()
        while not self._stop.wait(STEP):
            now, simulated = time.monotonic(), self._clock()
            left, right = self._wheel_speeds()
            self.model.step(simulated - last, (abs(left) + abs(right)) / 2.0, self._on_dock())
            last = simulated
            if now >= next_message:
                next_message = max(next_message + 1.0 / RATE, now)
                self._publisher.publish(self.message())

    def _on_dock(self):
        try:
            dock = self._dock()
        except Exception:  # the waypoints file broken, say: the battery goes on draining
            if not self._dock_failed:
                log.exception("simulated battery: where is the dock? (said once)")
            self._dock_failed = True
            return False
        if dock is None:
            return False
        return on_contacts(dock, self._pose())

    def message(self):
        """The model now as a ``sensor_msgs/BatteryState``."""
        msg = BatteryState()
        msg.header.stamp = rospy.Time.now()
        msg.percentage = self.model.charge
        msg.voltage = self.model.voltage
        msg.current = float("nan")
        msg.charge = msg.capacity = msg.design_capacity = float("nan")
        msg.power_supply_status = self.model.status
        msg.power_supply_health = BatteryState.POWER_SUPPLY_HEALTH_GOOD
        msg.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_LION
        msg.present = True
        msg.location = "base"
        return msg

    def close(self):
        """Stop publishing. Idempotent."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=2)
        publisher, self._publisher = self._publisher, None
        if publisher is not None:
            publisher.unregister()
