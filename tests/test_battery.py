"""The battery from ``sensor_msgs/BatteryState``: in ``/status``, as ``battery`` events, and the sim's own.

Real rosmaster and rospy: readings are published on the test's own topic and heard by the robot's
BatteryMonitor. The simulated robot's battery is checked end to end on a ``--sim`` server: it
drains while the robot drives and charges while it stands on its dock.
"""

import math

import pytest
import rospy
from sensor_msgs.msg import BatteryState

from flask_move_server.core.events import EventBus
from flask_move_server.core.reporter import BATTERY_OLD, Reporter, battery_news
from flask_move_server.ros.battery import BatteryMonitor
from flask_move_server.sim.battery import CHARGE_RATE, DRIVE_DRAIN, REST_DRAIN, STILL, BatteryModel
from tests.conftest import wait_for
from tests.fake_robot import FakeRobot
from tests.sse import EventReader

NAN = float("nan")


def reading(percentage=0.62, voltage=11.8, status=BatteryState.POWER_SUPPLY_STATUS_DISCHARGING):
    msg = BatteryState()
    msg.percentage, msg.voltage, msg.power_supply_status = percentage, voltage, status
    return msg


class Publisher:
    """Publishes on the robot's battery topic until the robot has heard the message sent (a new
    subscriber misses what was published before it connected)."""

    def __init__(self, topic):
        self.pub = rospy.Publisher(topic, BatteryState, queue_size=1)

    def until_heard(self, msg, heard):
        """Publish ``msg`` until ``heard()`` is true; returns its value."""
        return wait_for(lambda: self.pub.publish(msg) or heard(), timeout=10, interval=0.1,
                        message="the battery reading to be heard")

    def close(self):
        self.pub.unregister()


@pytest.fixture
def battery_topic(robot_config):
    publisher = Publisher(robot_config.battery.topic)
    yield publisher
    publisher.close()


def _battery(client):
    return client.get("/status").get_json()["battery"]


# /status, over real ROS ----------------------------------------------------------------


def test_nothing_heard_is_null(client):
    assert _battery(client) is None


def test_a_reading_is_in_status(client, battery_topic):
    battery = battery_topic.until_heard(reading(0.624, 11.834, BatteryState.POWER_SUPPLY_STATUS_CHARGING),
                                        lambda: _battery(client))
    assert battery["percentage"] == 62.4 and battery["voltage"] == 11.83 and battery["charging"] is True
    assert 0.0 <= battery["age"] < 5.0
    assert set(battery) == {"percentage", "voltage", "charging", "age"}


def test_the_latest_reading_wins_and_charging_follows_the_power_supply_status(client, battery_topic):
    cases = [(BatteryState.POWER_SUPPLY_STATUS_DISCHARGING, False), (BatteryState.POWER_SUPPLY_STATUS_FULL, False),
             (BatteryState.POWER_SUPPLY_STATUS_NOT_CHARGING, False), (BatteryState.POWER_SUPPLY_STATUS_UNKNOWN, None),
             (BatteryState.POWER_SUPPLY_STATUS_CHARGING, True), (99, None)]
    for index, (status, charging) in enumerate(cases):
        battery = battery_topic.until_heard(reading(0.5 + index / 100.0, 12.0, status),
                                            lambda index=index: _heard_percentage(client, 50.0 + index))
        assert battery["charging"] is charging, (status, battery)


def _heard_percentage(client, percentage):
    """The battery in /status once it says ``percentage``, else None."""
    battery = _battery(client)
    return battery if battery and battery["percentage"] == percentage else None


def test_unknown_and_nonsense_values_are_null_never_a_crash(client, battery_topic):
    battery = battery_topic.until_heard(reading(NAN, NAN, BatteryState.POWER_SUPPLY_STATUS_UNKNOWN),
                                        lambda: _battery(client))
    assert battery["percentage"] is None and battery["voltage"] is None and battery["charging"] is None
    for percentage, voltage in ((62.0, -3.0), (float("inf"), float("inf")), (-0.2, 0.0), (1.5, float("-inf"))):
        battery_topic.until_heard(reading(0.3, 10.0), lambda: (_battery(client) or {}).get("percentage") == 30.0)
        battery = battery_topic.until_heard(reading(percentage, voltage), lambda: (
            _battery(client) if _battery(client)["percentage"] != 30.0 else None))
        assert battery["percentage"] is None and battery["voltage"] is None, (percentage, voltage, battery)
    # float rounding at the ends is not nonsense: clamped to 0..100
    battery_topic.until_heard(reading(1.0001, 12.6), lambda: _heard_percentage(client, 100.0))
    assert client.get("/health").get_json()["ros"] == "connected"


def test_the_description_of_status_names_the_battery_and_its_fields(client, battery_topic):
    document = client.get("/openapi.json").get_json()
    status = document["paths"]["/status"]["get"]["responses"]["200"]["content"]["application/json"]["schema"]
    assert "battery" in status["required"] and status["properties"]["battery"]["nullable"] is True
    described = document["components"]["schemas"]["Battery"]
    battery = battery_topic.until_heard(reading(), lambda: _battery(client))
    assert set(described["properties"]) == set(described["required"]) == set(battery)


def test_an_old_reading_is_kept_and_its_age_tells(ros_node, unique_name):
    clock = Clock()
    monitor = BatteryMonitor(unique_name + "/battery_state", ros_node, clock=clock)
    publisher = Publisher(monitor.topic)
    try:
        publisher.until_heard(reading(0.8), monitor.status)
        clock.now += 95.0  # the publisher stopped
        assert monitor.status() == {"percentage": 80.0, "voltage": 11.8, "charging": False, "age": 95.0}
    finally:
        publisher.close()
        monitor.close()
        monitor.close()  # idempotent


# battery events ---------------------------------------------------------------------


class Clock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


class BatteryRobot(FakeRobot):
    def __init__(self):
        super().__init__()
        self.battery = None

    def status(self):
        return dict(super().status(), battery=dict(self.battery) if self.battery else None)


def _told(sub):
    told, event = [], sub.next(0)
    while event is not None:
        if event[0] == "battery":
            told.append(event[1])
        event = sub.next(0)
    return told


def test_battery_events_tell_what_a_person_would_notice_not_the_age_ticking():
    robot, bus = BatteryRobot(), EventBus()
    sub = bus.subscribe()
    reporter = Reporter(robot, bus)
    reporter.sample()
    assert _told(sub) == [], "no reading, no event: a robot without a fuel gauge tells none"

    robot.battery = {"percentage": 62.0, "voltage": 11.8, "charging": False, "age": 0.1}
    reporter.sample()
    assert _told(sub) == [robot.battery]
    for change in ({"age": 5.0}, {"percentage": 61.2}, {"voltage": 11.6}, {"age": 29.0}):
        robot.battery.update(change)
        reporter.sample()
        assert _told(sub) == [], change
    robot.battery["percentage"] = 61.0  # a whole point below the one told
    reporter.sample()
    assert [b["percentage"] for b in _told(sub)] == [61.0]
    robot.battery["charging"] = True
    reporter.sample()
    assert [b["charging"] for b in _told(sub)] == [True]
    robot.battery["age"] = BATTERY_OLD + 1  # its publisher stopped: told once, for the page to grey it
    reporter.sample()
    robot.battery["age"] += 10
    reporter.sample()
    assert [b["age"] for b in _told(sub)] == [BATTERY_OLD + 1]


def test_without_a_percentage_the_voltage_is_the_news():
    before = {"percentage": None, "voltage": 12.0, "charging": None, "age": 1.0}
    assert not battery_news(before, dict(before, voltage=11.95, age=3.0))
    assert battery_news(before, dict(before, voltage=11.9))
    assert battery_news(before, dict(before, percentage=50.0))
    assert not battery_news(dict(before, percentage=50.0), dict(before, percentage=50.5, voltage=11.0))


class Link:
    """The MQTT link as RobotState uses it: what it publishes, kept."""

    root = "flask-move-server/robo"

    def __init__(self):
        self.published = []

    def when_connected(self, callback):
        pass

    def publish(self, topic, payload, retain=False):
        self.published.append(payload)


def test_the_mqtt_state_tells_the_battery_as_news_not_its_age_ticking():
    from flask_move_server.mqtt.robot_state import RobotState

    robot, link, heard = BatteryRobot(), Link(), []
    state = RobotState(link, robot, battery_heard=lambda: heard.append(True), clock=Clock())
    assert state.tell() and not heard
    robot.battery = {"percentage": 62.0, "voltage": 11.8, "charging": False, "age": 0.1}
    assert state.tell() and heard == [True]  # Home Assistant's Battery sensor is due
    for age in (1.1, 2.1, 3.1):
        robot.battery = dict(robot.battery, age=age, percentage=62.0 - age / 10)
        assert not state.tell(), "a robot at rest would publish its state every second"
    robot.battery = dict(robot.battery, percentage=61.0)
    assert state.tell() and '"percentage": 61.0' in link.published[-1]


# the simulated battery -----------------------------------------------------------------


def test_the_model_drains_with_distance_and_time_and_charges_on_the_dock_when_still():
    model = BatteryModel(0.5)
    model.step(60.0, 0.0, on_dock=False)
    assert model.charge == pytest.approx(0.5 - 60 * REST_DRAIN)
    assert model.status == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    model.step(60.0, 0.3, on_dock=False)  # 18 m at the cruise speed
    assert model.charge == pytest.approx(0.5 - 120 * REST_DRAIN - 18 * DRIVE_DRAIN)
    before = model.charge
    model.step(10.0, 0.2, on_dock=True)  # driving over the dock does not charge
    assert model.charge < before and not model.charging
    model.step(10.0, STILL / 2, on_dock=True)
    assert model.charge == pytest.approx(before - 10 * (REST_DRAIN + 0.2 * DRIVE_DRAIN) + 10 * CHARGE_RATE)
    assert model.status == BatteryState.POWER_SUPPLY_STATUS_CHARGING
    model.step(3600.0, 0.0, on_dock=True)
    assert model.charge == 1.0 and model.status == BatteryState.POWER_SUPPLY_STATUS_FULL
    assert model.voltage == pytest.approx(12.6)
    model.step(1e9, 1.0, on_dock=False)
    assert model.charge == 0.0 and model.voltage == pytest.approx(9.9)
    # 20 minutes at the cruise speed: 100 % to about 60 %, as the demo wants
    model = BatteryModel(1.0)
    model.step(20 * 60.0, 0.3, on_dock=False)
    assert 0.55 <= model.charge <= 0.65


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    from tests.page_browser import PageSim

    # at 4 times real time (0.4 % a second on a dock), half full: never full before the test is done
    server = PageSim(tmp_path_factory.mktemp("battery_sim"), extra_config="  battery_start: 0.5\n")
    yield server
    server.close()


def _sim_battery(sim):
    return sim.status()["battery"]


def _go(sim, name):
    r = sim.post("/goto", {"name": name, "wait": 60}, timeout=70)
    assert r.status_code == 200 and r.json()["navigation"]["state"] == "succeeded", r.text


def put_dock(sim, x, y):
    import requests

    r = requests.put(sim.url + "/waypoints/dock", json={"x": x, "y": y, "yaw": 0.0}, headers=sim.headers(), timeout=10)
    assert r.status_code in (200, 201), r.text


def test_the_sim_battery_drains_while_driving_and_charges_on_the_dock(sim):
    first = wait_for(lambda: _sim_battery(sim), timeout=10, message="the sim's battery in /status")
    assert first["charging"] is True and 0.0 <= first["age"] <= 5.0, first  # it starts on its dock
    assert 50.0 <= first["percentage"] <= 80.0, first  # sim.battery_start, and charging since
    assert math.isclose(first["voltage"], 9.9 + 2.7 * first["percentage"] / 100, abs_tol=0.02)
    put_dock(sim, 6.2, 4.5)  # the dock is in the bedroom now: the robot stands off it (the sim reads it anew)
    wait_for(lambda: _sim_battery(sim)["charging"] is False, timeout=15, message="charging to end off the dock")

    with EventReader(sim.url, kinds=("battery",)) as events:
        kind, told = events.next()
        assert kind == "battery" and told["charging"] is False

    rest = _sim_battery(sim)  # standing: 0.2 % a minute of sim time, 0.8 % a minute here
    wait_for(lambda: _sim_battery(sim)["percentage"] < rest["percentage"], timeout=30,
             message="the battery draining at rest")

    leaving = _sim_battery(sim)["percentage"]
    _go(sim, "kitchen")
    arrived = _sim_battery(sim)
    assert arrived["charging"] is False
    assert arrived["percentage"] <= leaving - 0.5, (leaving, arrived)  # about 1 % for the 9 m drive

    r = sim.post("/dock", {"wait": 90}, timeout=100)  # onto the charger's contacts: a goal to the place is not
    assert r.status_code == 200 and r.json()["dock"]["state"] == "charging", r.text
    home = wait_for(lambda: _sim_battery(sim) if _sim_battery(sim)["charging"] else None, timeout=15,
                    message="charging on the dock")
    wait_for(lambda: _sim_battery(sim)["percentage"] >= home["percentage"] + 1.0, timeout=20,
             message="the battery charging")
    # A stream opened now, not one left unread through the drives: a reader that takes nothing for
    # server.channel_timeout (30 s; the drives take longer on a loaded machine) is disconnected.
    with EventReader(sim.url, kinds=("battery",)) as events:
        events.until(lambda kind, data: data["charging"] is True)
