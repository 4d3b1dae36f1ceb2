"""Who can command the robot through the broker, told where the owner looks: the doctor, the start-up log.

MQTT is a second way in that the HTTP token does not guard: whoever may publish on the robot's
topics can drive it (``goto/set``, a VDA 5050 order) and set its position (``initPosition``). The
broker's users and ACLs guard that (docs/home-assistant.md, "Who can drive the robot"). A robot
whose HTTP needs a token but which joins its broker anonymously, or in plain text over the
network, is told so as a warning (``mqtt_access``), and so is another client speaking as it
(``mqtt_identity``, from :class:`~flask_move_server.mqtt.identity.IdentityWatch`). Pure: no paho.
"""

import ipaddress

from flask_move_server.diagnostics.checks import PASS, WARN, Check

ACL_HINT = ("give the robot a broker user of its own and an ACL letting only it and Home Assistant write its "
            "topics (docs/home-assistant.md, \"Who can drive the robot\")")


def access_check(cfg, guarded):
    """``mqtt_access``: how the robot joins ``cfg``'s broker, against HTTP's guard (``guarded``: a token)."""
    where = "{}:{}".format(cfg.host, cfg.port)
    anonymous, clear = not cfg.username, not cfg.tls and not _loopback(cfg.host)
    if not anonymous and not clear:
        return Check("mqtt_access", PASS, "the broker {} is joined as '{}'{}".format(
            where, cfg.username, " over TLS" if cfg.tls else " on this machine"))
    how = " and ".join(w for w, on in (("anonymously", anonymous), ("in plain text", clear)) if on)
    if not guarded:
        return Check("mqtt_access", PASS, "the broker {} is joined {} (HTTP needs no token either)".format(where, how))
    summary = ("HTTP needs the token, but the broker {} is joined {}: anyone who may publish on this robot's "
               "topics can drive it and set its position".format(where, how))
    advice = []
    if anonymous:
        advice.append(ACL_HINT + " (mqtt.username, mqtt.password_file)")
    if clear:
        advice.append("turn on TLS (mqtt.tls, mqtt.ca_file, the broker's port 8883), so the password and the "
                      "commands do not cross the Wi-Fi in the clear")
    advice = "; ".join(advice)
    return Check("mqtt_access", WARN, summary, advice[:1].upper() + advice[1:] + ".")


def identity_check(status):
    """``mqtt_identity``: whether this robot's name on the broker is its own (``status``: the watch's)."""
    if status["state"] == "own":
        return Check("mqtt_identity", PASS, "no other client speaks as '{}' on the broker".format(status["name"]))
    return Check("mqtt_identity", WARN, status["message"],
                 "Give each robot a name of its own (mqtt.name, or mdns.hostname) and " + ACL_HINT + ".")


def mqtt_checks(link, guarded):
    """The doctor's MQTT lines for ``link``."""
    return [access_check(link.config, guarded), identity_check(link.identity.status())]


def _loopback(host):
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False
