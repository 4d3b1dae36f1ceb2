"""One connection to the owner's MQTT broker, which nothing else the robot does ever waits for.

- Availability: ``<root>/availability`` is ``online`` (retained) while connected; the broker's last
  will says ``offline`` (retained) when the robot vanishes; a clean ``offline`` on shutdown.
- Reconnects by itself (paho's loop, back-off 1 s to 30 s); on each connect it subscribes again
  and asks every owner (``when_connected``) to publish what it owns again.
- Out: :meth:`publish` never blocks. Messages wait in a bounded outbox for one sender thread;
  when the outbox is full, or the broker is away, they are dropped and counted, never queued
  without bound (what is retained is published again on the next connect anyway). paho's own
  queue is bounded too (QoS 1, ``outbox`` unacknowledged messages at most).
- In: a message on a handled topic waits in a small bounded inbox for one dispatcher thread, so a
  flood of commands is cut short (dropped and counted) and a slow command never holds paho's loop.
  Retained messages on command topics are ignored (a command left on the broker must not move the
  robot at start-up, as Valetudo rules), and so are payloads over ``MAX_PAYLOAD`` bytes.
- Identity: the robot listens to its own availability and state, and notices (and outlives) another
  client publishing there (:mod:`~flask_move_server.mqtt.identity`).

The broker's credentials and ACLs guard the commands (docs/home-assistant.md).
"""

import logging
import queue
import threading
from collections import Counter

from flask_move_server.core.errors import ConfigError
from flask_move_server.mqtt import paho_compat
from flask_move_server.mqtt.identity import IdentityWatch
from flask_move_server.process.log_limits import Throttled

log = logging.getLogger(__name__)

TOPIC_ROOT = "flask-move-server"
INBOX = 16  # commands waiting at most: a flood beyond this is dropped (a person taps a few a second)
MAX_PAYLOAD = 4096  # bytes: a command is a waypoint name or PRESS; anything bigger is not one
RECONNECT = (1, 30)  # s: paho's back-off between attempts, doubling from the first to the second
CLOSE_WAIT = 1.0  # s the clean "offline" may take on shutdown before we go anyway


class MqttLink:
    """The robot's MQTT connection: ``handle``/``when_connected`` before :meth:`start`."""

    def __init__(self, config, robot_name, make_client=paho_compat.make_client):
        self.config = config
        self.root = "{}/{}".format(TOPIC_ROOT, robot_name)
        self.availability = self.root + "/availability"
        self.counts = Counter()  # dropped_out, offline, dropped_in, retained, too_big, sent, received
        self._handlers = {}  # topic -> (callback(text), takes_retained, max_payload, too_big)
        self._owners = []
        self._will = (self.availability, "offline")
        self._last_words = [(self.availability, lambda: "offline")]
        self._outbox = queue.Queue(maxsize=config.outbox)
        self._inbox = queue.Queue(maxsize=INBOX)
        self._connected = threading.Event()
        self._closing = threading.Event()
        self._state = "starting"
        self._threads = []
        self._drops = Throttled(log, "MQTT drop warnings", burst=3, interval=60.0)
        self.identity = IdentityWatch(robot_name, (self.availability, self.root + "/state"),
                                      reassert=lambda topic, payload: self.publish(topic, payload, retain=True))
        self._client = make_client("{}-{}".format(TOPIC_ROOT, robot_name), self._on_connect,
                                   self._on_disconnect, self._on_message)

    # set-up ------------------------------------------------------------------

    def handle(self, topic, callback, takes_retained=False, max_payload=MAX_PAYLOAD, too_big=None):
        """Call ``callback(text)`` (in the dispatcher thread) for each message on ``topic``; a payload
        over ``max_payload`` bytes is dropped, and told to ``too_big(size)`` (quick: paho's thread)."""
        self._handlers[topic] = (callback, takes_retained, max_payload, too_big)

    def _matching(self, topic):
        """The handler of a pattern with ``+`` levels (``root/zone/+/set``) that ``topic`` matches, its callback
        told the topic too; None when none does."""
        levels = topic.split("/")
        for pattern, (callback, *rest) in self._handlers.items():
            parts = pattern.split("/")
            if "+" in parts and len(parts) == len(levels) and all(p in ("+", t) for p, t in zip(parts, levels)):
                return (lambda text, callback=callback: callback(text, topic)), *rest
        return None

    def set_will(self, topic, payload):
        """The broker's last will (one per connection): retained ``payload`` on ``topic``; before :meth:`start`.
        ``<root>/availability`` says ``offline`` otherwise."""
        self._will = (topic, payload)

    def say_on_close(self, topic, payload):
        """On a clean close, publish ``payload()`` (retained) on ``topic`` too, before disconnecting."""
        self._last_words.append((topic, payload))

    def when_connected(self, callback):
        """Call ``callback()`` after each connect (in paho's thread: publish, never wait)."""
        self._owners.append(callback)

    def start(self):
        """Connect in the background (the server never waits for the broker); returns self."""
        cfg, client = self.config, self._client
        client.will_set(self._will[0], self._will[1], qos=1, retain=True)
        if cfg.username:
            client.username_pw_set(cfg.username, _password(cfg))
        if cfg.tls:
            client.tls_set(ca_certs=cfg.ca_file)
        client.max_queued_messages_set(cfg.outbox)
        client.reconnect_delay_set(*RECONNECT)
        client.connect_async(cfg.host, cfg.port, cfg.keepalive)
        client.loop_start()
        for name, target in (("mqtt-sender", self._send_loop), ("mqtt-commands", self._dispatch_loop)):
            thread = threading.Thread(target=target, name=name, daemon=True)
            thread.start()
            self._threads.append(thread)
        log.info("MQTT: connecting to %s:%d as %s (topics under %s/)", cfg.host, cfg.port,
                 cfg.username or "anonymous", self.root)
        return self

    # out ---------------------------------------------------------------------

    def publish(self, topic, payload, retain=False, qos=1):
        """Queue ``payload`` (text) for ``topic``; False when it was dropped. Never blocks."""
        self.identity.sent(topic, payload, retain)
        try:
            self._outbox.put_nowait((topic, payload, retain, qos))
            return True
        except queue.Full:
            self._dropped("dropped_out", "MQTT: the outbox is full (%d messages; is the broker slow?): "
                          "dropped a message for %s", self.config.outbox, topic)
            return False

    def _send_loop(self):
        while True:
            item = self._outbox.get()
            if item is None:
                return
            if not self._connected.is_set():
                self.counts["offline"] += 1  # published again, if it is retained, on the next connect
                continue
            topic, payload, retain, qos = item
            try:
                info = self._client.publish(topic, payload, qos=qos, retain=retain)
            except Exception as exc:  # paho refusing a topic or payload must not end the sender
                log.warning("MQTT: could not publish to %s: %s", topic, exc)
                continue
            if paho_compat.published(info):
                self.counts["sent"] += 1
            else:
                self._dropped("dropped_out", "MQTT: the broker has not acknowledged %d messages; dropped one "
                              "for %s", self.config.outbox, topic)

    # in ----------------------------------------------------------------------

    def _on_message(self, topic, payload, retained):
        if topic in self.identity.topics:  # our own availability and state: who else speaks as this robot
            if not self._closing.is_set():
                self.identity.heard(topic, payload, retained)
            return
        handler = self._handlers.get(topic) or self._matching(topic)
        if handler is None:
            return
        callback, takes_retained, max_payload, too_big = handler
        if retained and not takes_retained:
            self.counts["retained"] += 1
            self._drops.log(logging.WARNING, "MQTT: ignored a retained message on %s (a command left on "
                            "the broker never moves the robot; clear it with an empty retained message)", topic)
            return
        if len(payload) > max_payload:
            self._dropped("too_big", "MQTT: ignored %d bytes on %s (at most %d bytes are taken there)",
                          len(payload), topic, max_payload)
            if too_big is not None:
                too_big(len(payload))
            return
        try:
            self._inbox.put_nowait((topic, callback, payload))
        except queue.Full:
            self._dropped("dropped_in", "MQTT: commands come faster than the robot takes them: dropped "
                          "one on %s", topic)

    def _dispatch_loop(self):
        while True:
            item = self._inbox.get()
            if item is None:
                return
            topic, callback, payload = item
            self.counts["received"] += 1
            try:
                callback(payload.decode("utf-8", "replace"))
            except Exception:  # one command's bug must not end the commands
                log.exception("MQTT: the command on %s failed", topic)

    # the connection ----------------------------------------------------------

    def _on_connect(self, ok, reason):
        if not ok:
            self._set_state("refused", "MQTT: %s:%d refused the connection: %s (trying again)",
                            self.config.host, self.config.port, reason)
            return
        self._connected.set()
        self._set_state("connected", "MQTT: connected to %s:%d", self.config.host, self.config.port)
        for topic in self._handlers:
            self._client.subscribe(topic, qos=1)
        for topic in self.identity.topics:
            self._client.subscribe(topic, qos=0)
        self.identity.connected()
        self.publish(self.availability, "online", retain=True)
        for owner in self._owners:
            try:
                owner()
            except Exception:
                log.exception("MQTT: publishing again after a connect failed")

    def _on_disconnect(self, reason):
        self._connected.clear()
        if not self._closing.is_set():
            self.identity.disconnected()
            self._set_state("disconnected", "MQTT: lost the broker (%s); reconnecting", reason or "closed")

    def _set_state(self, state, msg, *args):
        # A broker down for an hour is one line, not one per attempt; a client id taken again and again
        # (told once by the identity watch) is not two lines a second.
        if state != self._state and not self.identity.taken:
            log.log(logging.INFO if state == "connected" else logging.WARNING, msg, *args)
        self._state = state

    def _dropped(self, what, msg, *args):
        self.counts[what] += 1
        self._drops.log(logging.WARNING, msg, *args)

    # reading, closing --------------------------------------------------------

    @property
    def connected(self):
        return self._connected.is_set()

    def status(self):
        """What ``/status`` shows under ``mqtt``: the connection and what was dropped."""
        return {"state": self._state, "broker": "{}:{}".format(self.config.host, self.config.port),
                "topic_root": self.root, "identity": self.identity.status(), **{k: v for k, v in self.counts.items()
                                            if k in ("dropped_out", "dropped_in", "retained", "too_big")}}

    def close(self):
        """Say ``offline`` (waiting at most CLOSE_WAIT), disconnect, end the threads. Idempotent."""
        if self._closing.is_set():
            return
        self._closing.set()
        client = self._client
        if self._connected.is_set():
            try:
                sent = [client.publish(topic, words(), qos=1, retain=True) for topic, words in self._last_words]
                for info in sent:
                    info.wait_for_publish(CLOSE_WAIT)
            except Exception as exc:  # the broker went away meanwhile: its last will says the same
                log.info("MQTT: could not say offline: %s", exc)
        client.disconnect()
        client.loop_stop()
        self._connected.clear()
        for box in (self._outbox, self._inbox):
            _put_last(box)
        for thread in self._threads:
            thread.join(timeout=2)


def _put_last(box):
    """Wake the box's thread to end: make room for the None if the box is full."""
    while True:
        try:
            box.put_nowait(None)
            return
        except queue.Full:
            try:
                box.get_nowait()
            except queue.Empty:
                pass


def _password(cfg):
    """The broker password from ``password_file`` (its first line), or None without one."""
    if cfg.password_file is None:
        return None
    try:
        with open(cfg.password_file, encoding="utf-8") as f:
            return f.readline().rstrip("\r\n")
    except OSError as exc:
        raise ConfigError(cfg.password_file, "mqtt.password_file", "cannot read the MQTT password: {}".format(
            exc.strerror or exc))
