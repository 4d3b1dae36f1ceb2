"""One paho-mqtt client for both versions the robot meets: Debian bookworm's 1.6 and PyPI's 2.x.

paho 2.0 made the callbacks' arguments depend on a ``CallbackAPIVersion`` given to ``Client``
(which 1.x does not take). :func:`make_client` asks 2.x for its VERSION2 callbacks and hands our
code the same three everywhere:

- ``on_connect(ok, reason)``: the broker answered the CONNECT; ``reason`` a short text;
- ``on_disconnect(reason)``: the connection ended (``reason`` None when we ended it);
- ``on_message(topic, payload, retained)``.

Imports paho only (the one library of this adapter).
"""

import paho.mqtt.client as mqtt

VERSION2 = getattr(getattr(mqtt, "CallbackAPIVersion", None), "VERSION2", None)

# MQTT 3.1.1's CONNACK return codes (1.x passes them as ints; 2.x as ReasonCode objects with the name).
_REFUSED = {1: "unacceptable protocol version", 2: "identifier rejected", 3: "server unavailable",
            4: "bad user name or password", 5: "not authorized"}


def make_client(client_id, on_connect, on_disconnect, on_message):
    """A paho ``Client`` (MQTT 3.1.1, clean session) whose callbacks call ours."""
    if VERSION2 is not None:
        client = mqtt.Client(VERSION2, client_id=client_id, clean_session=True, protocol=mqtt.MQTTv311)
        client.on_connect = lambda c, u, flags, code, props=None: on_connect(not _failed(code), _text(code))
        client.on_disconnect = lambda c, u, flags, code, props=None: on_disconnect(
            _text(code) if _failed(code) else None)
    else:
        client = mqtt.Client(client_id=client_id, clean_session=True, protocol=mqtt.MQTTv311)
        client.on_connect = lambda c, u, flags, rc: on_connect(rc == 0, _REFUSED.get(rc, "refused ({})".format(rc)))
        client.on_disconnect = lambda c, u, rc: on_disconnect(None if rc == 0 else mqtt.error_string(rc))
    client.on_message = lambda c, u, message: on_message(message.topic, message.payload, bool(message.retain))
    return client


def _failed(code):
    is_failure = getattr(code, "is_failure", None)
    return bool(is_failure) if is_failure is not None else code != 0


def _text(code):
    name = getattr(code, "getName", None)
    return name() if name is not None else str(code)


def published(info):
    """True when paho took a message (``publish``'s answer, in both versions)."""
    return info.rc == mqtt.MQTT_ERR_SUCCESS
