"""Hand-edited YAML read within bounds: a size cap, no anchors or aliases, no deep nesting.

A file anyone may drop into a folder the server reads (a map YAML) must not stall or
flood the process: aliases let a few hundred bytes expand to hundreds of megabytes
(the "billion laughs"), a few megabytes of YAML take PyYAML's pure-Python parser a
minute, and thousands of nested brackets overflow Python's stack. So the file's size is
checked before it is read, its events are scanned (anchors, aliases and nesting deeper
than :data:`MAX_DEPTH` refused) before anything is built, and libyaml's C parser is used
where PyYAML has it. Every refusal is a :class:`YamlRefused` with a short reason saying where
and what, never the file's text (:func:`flask_move_server.waypoints.safe_yaml.describe`).
Pure: PyYAML only.
"""

import os
import stat

import yaml

from flask_move_server.waypoints import safe_yaml

MAX_DEPTH = 32  # levels of nested mappings and lists; a map YAML has 2
_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_START = (yaml.MappingStartEvent, yaml.SequenceStartEvent)
_END = (yaml.MappingEndEvent, yaml.SequenceEndEvent)


def _cut(text, limit):
    return text if len(text) <= limit else text[:limit - 1] + "\u2026"


class YamlRefused(ValueError):
    """The file is not YAML this reader takes: too big, not a regular file, an alias, too deep, invalid."""


def read(path, max_bytes):
    """The data of the YAML file ``path``, at most ``max_bytes`` long; OSError, YamlRefused."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            raise YamlRefused("not a regular file")
        data = f.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise YamlRefused("larger than the {} bytes such a file may have".format(max_bytes))
    try:
        return load(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise YamlRefused("not UTF-8 text") from None


def load(text):
    """The data of YAML ``text``: anchors, aliases and nesting past MAX_DEPTH refused first."""
    try:
        _check_events(text)
        return yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader
    except YamlRefused:
        raise
    except yaml.YAMLError as exc:  # where and what, never the file's text (it may be a link to a secret)
        raise YamlRefused("not valid YAML: " + _cut(safe_yaml.describe(exc), 200)) from None
    except Exception as exc:  # noqa: BLE001 - hostile text: whatever the parser raises, it is unreadable
        raise YamlRefused("cannot be read ({})".format(type(exc).__name__)) from None


def _check_events(text):
    depth = 0
    for event in yaml.parse(text, Loader=_Loader):
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise YamlRefused("anchors and aliases ('&', '*') are not allowed")
        if isinstance(event, _START):
            depth += 1
            if depth > MAX_DEPTH:
                raise YamlRefused("nested deeper than {} levels".format(MAX_DEPTH))
        elif isinstance(event, _END):
            depth -= 1
