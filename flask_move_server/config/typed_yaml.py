"""Typed YAML: build a dataclass tree from plain data, validating every key on the way.

Generic: it knows dataclasses, ``Optional``, ``Literal``, lists, dicts and scalars, and nothing of
robots. A field may carry metadata the loader acts on: ``check`` (a function returning a reason
or None, see :func:`checked`; a key whose default fails its check must be given), ``path``
(relative to the file's folder, see :func:`path_field`) and ``internal`` (not a key of the file). Every problem is a
:class:`~flask_move_server.core.errors.ConfigError` naming the source, the dotted key and the reason;
an unknown key suggests the closest known one, because a typo must not fall back to a default.
"""

import dataclasses
import difflib
import math
import os
import typing
from dataclasses import field
from typing import Any, Dict, List, Literal, get_args, get_origin

from flask_move_server.core.errors import ConfigError


def checked(check, **kw):
    """A dataclass field validated by ``check(value)``, which returns None or the reason it is wrong."""
    return field(metadata={"check": check}, **kw)


def path_field(**kw):
    """A dataclass field holding a file path, made absolute against the config file's folder."""
    return field(metadata={"path": True}, **kw)


def internal_field(**kw):
    """A dataclass field that is not a key of the file (e.g. where the values came from)."""
    return field(metadata={"internal": True}, **kw)


def build(cls, data, source="(config)", base_dir=".", prefix=""):
    """Build dataclass ``cls`` from the mapping ``data``, validating every key."""
    if not isinstance(data, dict):
        raise ConfigError(source, prefix.rstrip(".") or None, "must be a mapping, got {}".format(_kind(data)))
    fields = {f.name: f for f in dataclasses.fields(cls) if not f.metadata.get("internal")}
    _refuse_unknown(data, fields, source, prefix, getattr(cls, "MOVED", {}))
    hints = typing.get_type_hints(cls)
    values = {}
    for name, value in data.items():
        f = fields[name]
        key = prefix + name
        values[name] = _coerce(hints[name], value, source, key, base_dir)
        if value is not None and f.metadata.get("path"):
            values[name] = os.path.normpath(os.path.join(base_dir, os.path.expanduser(values[name])))
        check = f.metadata.get("check")
        problem = check(values[name]) if check and values[name] is not None else None
        if problem:
            raise ConfigError(source, key, "{} (got {!r})".format(problem, value))
    _refuse_missing(fields, data, source, prefix)
    return cls(**values)


def _refuse_missing(fields, data, source, prefix):
    """A checked key whose default fails its own check (a webhook's ``url: ""``) must be given."""
    for name, f in fields.items():
        check = f.metadata.get("check")
        if name in data or not check or f.default is dataclasses.MISSING:
            continue
        problem = check(f.default) if f.default is not None else None
        if problem:
            raise ConfigError(source, prefix + name, "missing: it {}".format(problem))


def _refuse_unknown(data, fields, source, prefix, moved):
    """An unknown key is an error: a key that moved elsewhere says where, another a close name."""
    unknown = [k for k in data if k not in fields]
    if unknown:
        key = str(unknown[0])
        if key in moved:
            raise ConfigError(source, prefix + key, "no longer a setting, remove it: " + moved[key])
        close = difflib.get_close_matches(key, list(fields), n=1)
        hint = "; did you mean {!r}?".format(close[0]) if close else "; known keys: {}".format(", ".join(fields))
        raise ConfigError(source, prefix + key, "unknown key" + hint)


def _coerce(hint, value, source, key, base_dir):
    origin = get_origin(hint)
    if origin is typing.Union:
        inner = [a for a in get_args(hint) if a is not type(None)]
        return None if value is None else _coerce(inner[0], value, source, key, base_dir)
    if origin is Literal:
        choices = get_args(hint)
        if value not in choices:
            raise ConfigError(source, key, "must be one of {} (got {!r})".format(", ".join(choices), value))
        return value
    if origin in (list, List):
        if not isinstance(value, list):
            raise ConfigError(source, key, "must be a list, got {}".format(_kind(value)))
        (item,) = get_args(hint)
        return [_coerce(item, v, source, "{}[{}]".format(key, i), base_dir) for i, v in enumerate(value)]
    if origin in (dict, Dict):
        if not isinstance(value, dict):
            raise ConfigError(source, key, "must be a mapping, got {}".format(_kind(value)))
        return dict(value)
    if dataclasses.is_dataclass(hint):
        return build(hint, {} if value is None else value, source, base_dir, key + ".")
    return _scalar(hint, value, source, key)


def _scalar(hint, value, source, key):
    if hint is Any:
        return value
    if hint is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(source, key, "must be true or false, got {!r}".format(value))
    if hint is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise ConfigError(source, key, "must be a whole number, got {!r}".format(value))
    if hint is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
            return float(value)
        raise ConfigError(source, key, "must be a finite number, got {!r}".format(value))
    if hint is str:
        if isinstance(value, str):
            return value
        raise ConfigError(source, key, "must be text, got {!r}".format(value))
    raise ConfigError(source, key, "unsupported setting type {}".format(hint))


def _kind(value):
    return {dict: "a mapping", list: "a list", str: "text"}.get(type(value), repr(value))


def as_plain(tree):
    """The dataclass ``tree`` as nested dicts in the file's shape (internal fields left out)."""
    if isinstance(tree, list):
        return [as_plain(v) for v in tree]
    if isinstance(tree, dict):
        return {k: as_plain(v) for k, v in tree.items()}
    if not dataclasses.is_dataclass(tree):
        return tree
    return {f.name: as_plain(getattr(tree, f.name)) for f in dataclasses.fields(tree)
            if not f.metadata.get("internal")}


def merge(base, override):
    """``base`` with ``override``'s keys laid over it, mapping by mapping."""
    result = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(result.get(key), dict):
            result[key] = merge(result[key], value)
        else:
            result[key] = value
    return result
