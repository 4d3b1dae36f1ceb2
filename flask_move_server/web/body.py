"""Reading request bodies: JSON whatever the Content-Type, strictly validated."""

import json
import math

from flask import current_app, request

from flask_move_server.core.errors import BadRequest, BodyTooLarge, shown


def _no_constants(name):
    raise ValueError("{} is not a number JSON allows".format(name))


def _unique_keys(pairs):
    """A JSON object whose keys are all different: ``{"x": 1, "x": 1e9}`` is ambiguous, not the last one."""
    data = {}
    for key, value in pairs:
        if key in data:
            raise BadRequest("The field {} appears twice in the body; send each field once.".format(shown(key)))
        data[key] = value
    return data


# Built once: json.loads with these arguments builds a decoder (and its scanner) on every call.
_STRICT_JSON = json.JSONDecoder(parse_constant=_no_constants, object_pairs_hook=_unique_keys)


def json_object(allowed, required=True):
    """The request body as a dict with only the ``allowed`` keys; {} if empty and not required."""
    raw = _read_body()
    if not raw.strip():
        if required:
            raise BadRequest("This endpoint needs a JSON object body, e.g. {}.".format(_example(allowed)))
        return {}
    try:
        data = _STRICT_JSON.decode(raw.decode("utf-8"))
    except BadRequest:
        raise
    except RecursionError:
        raise BadRequest("The JSON body is nested too deeply.")
    except (UnicodeDecodeError, ValueError) as exc:
        raise BadRequest("The body is not valid JSON ({}): send a JSON object, e.g. {}.".format(exc, _example(allowed)))
    if not isinstance(data, dict):
        raise BadRequest("The body must be a JSON object, e.g. {}.".format(_example(allowed)))
    unknown = sorted(set(data) - set(allowed))
    if unknown:
        takes = "takes " + ", ".join(sorted(allowed)) if allowed else "takes no fields"
        raise BadRequest("Unknown field {} (this endpoint {}).".format(shown(unknown[0]), takes))
    return data


def _read_body():
    """The raw body, refused past the size limit (werkzeug < 2.3 does not enforce it in get_data).

    A body with a plain ``Content-Length`` (waitress gives one to every body, chunked ones too, and
    has it whole before the app runs) is read straight from ``wsgi.input``: werkzeug's stream
    wrappers cost more than the rest of a ``/goto`` body's parsing, before its goal is published.
    """
    limit = current_app.config["MAX_CONTENT_LENGTH"]
    environ = request.environ
    declared = environ.get("CONTENT_LENGTH", "")
    if not declared.isdigit() or not declared.isascii():
        raw = request.get_data(cache=True)  # anything else: werkzeug's careful way
    elif len(declared) > 18 or int(declared) > limit:
        raw = None
    else:
        raw = environ["wsgi.input"].read(int(declared))
    if raw is None or len(raw) > limit:
        raise BodyTooLarge("The request body is larger than {} bytes.".format(limit))
    return raw


def number(data, key, minimum=None, maximum=None):
    """``data[key]`` as a finite float within bounds, else BadRequest naming the field."""
    if key not in data:
        raise BadRequest("Field {!r} is required.".format(key))
    value = data[key]
    try:
        finite = not isinstance(value, bool) and isinstance(value, (int, float)) and math.isfinite(value)
    except OverflowError:  # an integer beyond any float, e.g. 1 followed by 400 zeros
        finite = False
    if not finite:
        raise BadRequest("Field {!r} must be a finite number, got {}.".format(key, json.dumps(value)[:40]))
    if minimum is not None and value < minimum or maximum is not None and value > maximum:
        raise BadRequest("Field {!r} must be between {} and {}, got {}.".format(key, minimum, maximum, value))
    return float(value)


def text(data, key):
    """``data[key]`` as text, else BadRequest naming the field."""
    if key not in data:
        raise BadRequest("Field {!r} is required.".format(key))
    value = data[key]
    if not isinstance(value, str):
        raise BadRequest("Field {!r} must be text, got {}.".format(key, json.dumps(value)[:40]))
    return value


_EXAMPLES = {
    frozenset({"name", "x", "y", "yaw", "wait", "valid_until"}): '{"name": "kitchen"}',
    frozenset({"linear", "angular", "valid_until"}): '{"linear": 0.2, "angular": 0.0}',
    frozenset({"x", "y", "yaw", "from", "dock"}): '{"x": 1.0, "y": 2.0, "yaw": 0.0} or {"from": "current"}',
    frozenset({"mode", "map", "pose", "wait"}): '{"mode": "navigation", "map": "flat"}',
    frozenset({"x", "y", "yaw", "name"}): '{"x": 1.0, "y": 2.0, "yaw": 0.0} or {"name": "dock"}',
    frozenset({"x", "y", "yaw", "name", "confirm"}):
        '{"x": 1.0, "y": 2.0, "yaw": 0.0}, {"name": "dock"} or {"confirm": true}',
    frozenset({"name", "overwrite", "then"}): '{"name": "flat"}',
}


def _example(allowed):
    return _EXAMPLES.get(frozenset(allowed), "{...}")
