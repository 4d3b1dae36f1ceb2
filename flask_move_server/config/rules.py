"""The rules a config value is checked by: each returns None, or the reason a user reads. Pure.

Used by the schema in config.py through ``typed_yaml.checked(rule, default=...)``; the
reason is printed after the file and the key, as in ``robot.yaml: server.port: must be a TCP
port, 0 to 65535``.
"""

import re


def positive(value):
    return None if value > 0 else "must be greater than 0"


def non_negative(value):
    return None if value >= 0 else "must be 0 or more"


def tcp_port(value):
    return None if 0 <= value <= 65535 else "must be a TCP port, 0 to 65535"


def dns_label(value):
    if value.endswith(".local"):
        return "must be the name without .local ({!r}, not {!r})".format(value[: -len(".local")], value)
    valid = 0 < len(value) <= 63 and value[0] != "-" and value[-1] != "-" and all(
        c.isascii() and (c.isalnum() or c == "-") for c in value
    )
    return None if valid else "must be 1 to 63 letters, digits or '-' (not at either end), like robot"


def instance_name(value):
    if "." in value:
        return "must not contain '.' (it separates DNS labels)"
    if 0 < len(value.encode("utf-8")) <= 63:
        return None
    return "must be 1 to 63 bytes of text"


def host_names(value):
    for name in value:
        if name != "*" and not re.fullmatch(r"\.?[A-Za-z0-9_-]+(\.[A-Za-z0-9_-]+)*\.?", name):
            return "must list host names (robot.lan), domains (.lan) or '*', got {!r}".format(name)
    return None


def speed_factor(value):
    return None if 0 < value <= 20 else "must be above 0 and at most 20 (simulated seconds per real second)"


def fraction(value):
    return None if 0 <= value <= 1 else "must be between 0 and 1"


def gpio_pin(value):
    return None if value is None or 0 <= value <= 27 else "must be a BCM GPIO number, 0 to 27"


def debounce_seconds(value):
    return None if 0 <= value <= 1 else "must be 0 to 1 seconds"


def launch_command(value):
    parts = value.split()
    if len(parts) == 2 and parts[1].endswith(".launch"):
        return None
    return "must be 'PACKAGE FILE.launch', like 'flask_move_server mapping.launch'"


def web_url(value):
    """An http(s) URL with a host: a webhook never goes to file://, gopher:// or a bare path."""
    match = re.fullmatch(r"(?i)(https?)://([^/?#\s]+)[^\s]*", value)
    if match and "@" not in match.group(2):
        return None
    return "must be an http:// or https:// URL with a host and no user:password@ part, like http://hub.lan:8123/api/webhook/robot"


def mqtt_topic_part(value):
    if value and not any(c in value for c in "/+#\0") and len(value.encode("utf-8")) <= 64:
        return None
    return "must be 1 to 64 bytes without '/', '+', '#'"
