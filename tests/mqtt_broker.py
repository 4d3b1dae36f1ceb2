"""A real MQTT broker for the tests (Debian's ``mosquitto`` on a free port of 127.0.0.1), and a
client that listens as Home Assistant does.

``Broker`` starts, kills and restarts mosquitto on the same port (no persistence: a restart forgets
every retained message, as a broker that lost its disk would). ``Listener`` is a paho client,
subscribed to everything, that keeps each message with its retained flag and publishes commands
as Home Assistant's MQTT integration does (QoS 0, not retained).
"""

import json
import shutil
import subprocess
import threading
import time

import paho.mqtt.client as mqtt

from tests.conftest import free_port, stop_process, wait_for


class Broker:
    """mosquitto on 127.0.0.1:``port``, anonymous clients allowed, nothing kept on disk."""

    def __init__(self, folder):
        self.port = free_port()
        self.conf = folder / "mosquitto.conf"
        self.conf.write_text("listener {} 127.0.0.1\nallow_anonymous true\npersistence false\n"
                             "log_dest stderr\n".format(self.port))
        self.proc = None
        self.start()

    def start(self):
        exe = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
        self.proc = subprocess.Popen([exe, "-c", str(self.conf)], stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
        wait_for(self._answers, timeout=10, message="mosquitto on port {}".format(self.port))
        return self

    def _answers(self):
        import socket

        try:
            socket.create_connection(("127.0.0.1", self.port), timeout=0.2).close()
            return True
        except OSError:
            return False

    def kill(self):
        self.proc.kill()
        self.proc.wait()

    def stop(self):
        stop_process(self.proc)


class Listener:
    """A paho client on ``broker``, subscribed to ``topics`` (everything by default)."""

    def __init__(self, broker, topics=("#",)):
        version = getattr(mqtt, "CallbackAPIVersion", None)
        self.client = mqtt.Client(version.VERSION2) if version else mqtt.Client()
        self.messages = []  # (monotonic time, topic, text, retained)
        self._lock = threading.Lock()
        self._subscribed = threading.Event()
        self.client.on_message = self._keep
        self.client.on_subscribe = lambda *args: self._subscribed.set()
        self.client.connect("127.0.0.1", broker.port)
        self.client.loop_start()
        for topic in topics:
            self.client.subscribe(topic, qos=1)
        if topics:
            wait_for(self._subscribed.is_set, message="the listener's subscription")

    def _keep(self, client, userdata, message):
        with self._lock:
            self.messages.append((time.monotonic(), message.topic, message.payload.decode("utf-8", "replace"),
                                  bool(message.retain)))

    def clear(self):
        with self._lock:
            self.messages.clear()

    def on(self, topic):
        """Every message seen on ``topic``, oldest first: ``(time, text, retained)``."""
        with self._lock:
            return [(t, text, retained) for t, top, text, retained in self.messages if top == topic]

    def last(self, topic):
        seen = self.on(topic)
        return seen[-1][1] if seen else None

    def wait_last(self, topic, predicate=lambda text: True, timeout=10, message=None):
        """The newest text on ``topic`` once ``predicate`` holds for it."""
        return wait_for(lambda: (lambda t: t if t is not None and predicate(t) else None)(self.last(topic)),
                        timeout=timeout, message=message or "a message on {}".format(topic))

    def wait_json(self, topic, predicate=lambda data: True, timeout=10, message=None):
        """The newest JSON object on ``topic`` once ``predicate`` holds for it."""
        text = self.wait_last(topic, lambda t: bool(t) and predicate(json.loads(t)), timeout, message)
        return json.loads(text)

    def send(self, topic, payload, retain=False):
        """Publish as Home Assistant does (QoS 0); waits until it left."""
        self.client.publish(topic, payload, qos=0, retain=retain).wait_for_publish(5)

    def close(self):
        self.client.loop_stop()
        self.client.disconnect()


def retained_on(broker, topic, wait=1.0):
    """What the broker keeps retained on ``topic`` now (a fresh subscriber's view), or None."""
    listener = Listener(broker, topics=(topic,))
    try:
        time.sleep(wait)
        seen = [text for _t, text, retained in listener.on(topic) if retained]
        return seen[-1] if seen else None
    finally:
        listener.close()
