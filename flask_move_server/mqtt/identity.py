"""The robot's identity on the broker: a name of its own by default, and noticing who else uses it.

Two robots left at the default name ``robot`` used to share one client id and one set of topics:
they knocked each other off the broker every second and one Home Assistant command drove both.
:func:`broker_name` gives a robot left at the default a name of its own (``robot-<6 hex>`` from a
hash of its machine id: the same at every start, told in the log), unless ``mqtt.name`` names it.

:class:`IdentityWatch` notices someone else using that identity, as Valetudo's and Zigbee2MQTT's
owners are used to being told: the robot subscribes to its own ``availability`` and ``state`` and
remembers what it published there. A live message on them that is not one of its own is someone
else's (a second robot of the same name, or any client faking the robot's state for Home
Assistant): it is counted, told in ``/status`` and the doctor (``mqtt_identity``) and the log
(throttled), and the robot re-asserts its own retained messages (at most once every
:data:`REASSERT` s per topic, so two robots sharing a name do not flood the broker). A retained
message found on subscribing is the broker's memory of this robot's last life: never counted, and
covered by what the robot publishes on every connect. A broker that drops the connection within
seconds of each connect, again and again, is what a second client with the same client id looks
like; that is told too. Pure: no paho (the link calls it), no rospy.
"""

import collections
import hashlib
import logging
import threading
import time

from flask_move_server.process.log_limits import Throttled

log = logging.getLogger(__name__)

DEFAULT_HOSTNAME = "robot"  # mdns.hostname's default
MACHINE_ID_FILES = ("/etc/machine-id", "/var/lib/dbus/machine-id")
REMEMBERED = 32  # payloads of our own kept per topic: the echo of each arrives within a moment
REASSERT = 5.0  # s: our own retained messages published again at most this often per topic
QUIET = 120.0  # s without a foreign message before the identity is told as the robot's own again
WILL_WINDOW = 2.0  # s after a connect in which an "offline" is the will of our own connection a takeover ended
KNOCKED_OFF = 10.0  # s: a connection the broker ends sooner than this after the connect was "knocked off"
KNOCKS = 3  # knock-offs in a row before a second client with this client id is told


def broker_name(mqtt_name, hostname, machine_id_files=MACHINE_ID_FILES):
    """The robot's name on the broker: ``mqtt.name``; else the mDNS host name; else, for a robot left at
    the default ``robot``, ``robot-<6 hex>`` from its machine id (the same at every start)."""
    if mqtt_name:
        return mqtt_name
    if hostname != DEFAULT_HOSTNAME:
        return hostname
    machine = _machine_id(machine_id_files)
    if machine is None:
        log.warning("MQTT: this machine has no machine id (%s), so the robot is '%s' on the broker like any other "
                    "robot left at the default name; set mqtt.name (or mdns.hostname) to a name of its own",
                    " or ".join(machine_id_files), hostname)
        return hostname
    return "{}-{}".format(hostname, hashlib.sha256(b"flask-move-server:" + machine.encode()).hexdigest()[:6])


def _machine_id(files):
    for path in files:
        try:
            with open(path, encoding="ascii") as f:
                text = f.read(64).strip()
        except (OSError, UnicodeDecodeError):
            continue
        if text:
            return text
    return None


class IdentityWatch:
    """Who else speaks as this robot: told each publish of ours (:meth:`sent`) and each message heard on our
    own topics (:meth:`heard`); ``reassert(topic, payload)`` publishes one of ours again, retained."""

    def __init__(self, name, topics, reassert, clock=time.monotonic):
        """``topics``: the availability topic first, then the state's."""
        self.name = name
        self.topics = tuple(topics)
        self._reassert, self._clock = reassert, clock
        self._lock = threading.Lock()
        self._ours = {topic: collections.deque(maxlen=REMEMBERED) for topic in self.topics}
        self._last = {}  # topic -> the newest payload of ours (text), retained
        self._reasserted = {}  # topic -> when we last published it again
        self._foreign, self._foreign_at, self._first_at = 0, None, None
        self._connected_at, self._knocks = None, 0
        self._warnings = Throttled(log, "MQTT identity warnings", burst=2, interval=60.0)

    def sent(self, topic, payload, retain):
        """We publish ``payload`` (text) on ``topic``; its echo is ours."""
        if topic in self._ours:
            with self._lock:
                self._ours[topic].append(_digest(payload.encode("utf-8")))
                if retain:
                    self._last[topic] = payload

    def heard(self, topic, payload, retained):
        """A message on one of our own topics (paho's thread: quick, never waits)."""
        if retained:
            return  # the broker's memory of our last life: what we publish on connecting replaces it
        with self._lock:
            again, foreign = self._judge(topic, payload)
        if foreign:
            self._warnings.log(logging.WARNING, "MQTT: another client published on %s, this robot's own topic (a "
                               "second robot named '%s' on this broker, or someone faking it); %s. Give each robot "
                               "a name of its own (mqtt.name) and the broker a user per robot "
                               "(docs/home-assistant.md)", topic, self.name,
                               "this robot's own message published again" if again is not None else
                               "its own is published again within {:g} s".format(REASSERT))
        if again is not None:
            self._reassert(topic, again)

    def _judge(self, topic, payload):
        """Lock held: (our own message to publish again, or None; whether ``payload`` was someone else's)."""
        if _digest(payload) in self._ours[topic]:
            return None, False
        now = self._clock()
        if self._our_last_will(topic, payload, now):
            self._reasserted[topic] = now
            return self._last.get(topic), False
        if self._foreign_at is None or now - self._foreign_at > QUIET:
            self._first_at = time.time()
        self._foreign, self._foreign_at = self._foreign + 1, now
        if now - self._reasserted.get(topic, -REASSERT) < REASSERT:
            return None, True
        self._reasserted[topic] = now
        return self._last.get(topic), True

    def _our_last_will(self, topic, payload, now):
        """An ``offline`` on our availability just after we connected: the broker publishes the will of our
        own connection that died (a takeover on reconnecting), not someone else's."""
        return (topic == self.topics[0] and payload == b"offline" and self._connected_at is not None and
                now - self._connected_at < WILL_WINDOW)

    def connected(self):
        self._connected_at = self._clock()

    def disconnected(self):
        """The broker ended the connection: soon after its connect, again and again, is a client id taken over."""
        if self._connected_at is None:
            return
        quick = self._clock() - self._connected_at < KNOCKED_OFF
        self._connected_at = None
        self._knocks = self._knocks + 1 if quick else 0
        if self._knocks == KNOCKS:
            log.warning("MQTT: the broker ended %d connections in a row within %g s of each connect: another client "
                        "connects with this robot's client id 'flask-move-server-%s' (a second robot of the same "
                        "name?); give each robot a name of its own (mqtt.name)", KNOCKS, KNOCKED_OFF, self.name)

    @property
    def taken(self):
        """True while another client keeps taking this robot's client id (the link then logs no flip)."""
        return self._knocks >= KNOCKS

    def status(self):
        """What ``/status`` shows under ``mqtt.identity``: ``own``, ``shared`` (someone else publishes as this
        robot, within the last :data:`QUIET` s) or ``taken`` (its client id keeps being taken over)."""
        with self._lock:
            recent = self._foreign_at is not None and self._clock() - self._foreign_at <= QUIET
            state = "taken" if self._knocks >= KNOCKS else "shared" if recent else "own"
            told = {"name": self.name, "state": state, "foreign_messages": self._foreign}
            if state == "shared":
                told["since"] = time.strftime("%Y-%m-%dT%H:%M:%S%z", time.localtime(self._first_at))
                told["message"] = ("Another client publishes on this robot's own topics (flask-move-server/{}/): a "
                                   "second robot of that name, or someone faking it.".format(self.name))
            elif state == "taken":
                told["message"] = ("The broker keeps ending this robot's connection right after it connects: "
                                   "another client uses its client id flask-move-server-{}.".format(self.name))
            return told


def _digest(data):
    return hashlib.blake2b(data, digest_size=16).digest()
