"""YAML from a hand-edited file, read as hostile text: bounded, and never quoted back.

Two kinds of file come from people, and both are read here:

- The waypoints files are edited by hand and may be links to anything. :func:`load` refuses what
  could blow up (anchors and aliases, nesting past :data:`MAX_DEPTH`, a name given twice) and
  gives a :class:`Document`, with the line of each key for the errors that follow.
- A file anyone may drop into a folder the server reads (a map YAML) must not stall or flood the
  process: aliases let a few hundred bytes expand to hundreds of megabytes (the "billion laughs"),
  a few megabytes of YAML take PyYAML's pure-Python parser a minute, and thousands of nested
  brackets overflow Python's stack. :func:`read` checks the file's size before reading it, scans
  its events (anchors, aliases and nesting deeper than :data:`READ_MAX_DEPTH` refused) before
  anything is built, and uses libyaml's C parser where PyYAML has it.

Whatever the parser raises is :class:`Unreadable`, saying *where* and *what* is wrong (line,
column, PyYAML's problem) without the text itself: an error about a file linked to a secret must
not show its lines in an API answer or the log. Pure: PyYAML only.
"""

import collections
import collections.abc
import os
import re
import stat

import yaml

MAX_DEPTH = 16  # levels of nesting: a waypoints file needs 4 (file, waypoints, entry, coordinate)
READ_MAX_DEPTH = 32  # levels of nested mappings and lists in a file read(); a map YAML has 2
# In PyYAML's problems, quoted syntax ('<block end>', ',', '\t') says what is wrong; other quoted
# text (a tag, a handle) is the file's own and is left out.
_QUOTED = re.compile(r""" ?('[^']*'|"[^"]*")""")
_SYNTAX = re.compile(r"""['"](<[a-z ]+>|.|\\.|\\x[0-9a-f]{2}|\\u[0-9a-f]{4})['"]""")


class Unreadable(ValueError):
    """Not YAML these readers take (too big, not a regular file, an alias, too deep, invalid); the
    message says where and what, never the text."""


class _GuardedLoader(yaml.SafeLoader):
    """SafeLoader that rejects a key given twice, any anchor or alias, and deep nesting.

    Aliases let a few hundred bytes expand to megabytes (in memory, in error messages, in
    /status). Nesting is refused before PyYAML's recursion could reach Python's limit (5,000
    brackets were a RecursionError).
    """

    def __init__(self, stream):
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise yaml.composer.ComposerError(
                None, None, "anchors and aliases ('&', '*') are not allowed in a waypoints file", event.start_mark)
        if self._depth >= MAX_DEPTH:
            raise yaml.composer.ComposerError(
                None, None, "nested more than {} levels deep".format(MAX_DEPTH), event.start_mark)
        self._depth += 1
        try:
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_object(self, node, deep=False):
        try:
            return super().construct_object(node, deep)
        except (ArithmeticError, LookupError, TypeError, ValueError):  # a date like 2001-13-45, say
            raise yaml.constructor.ConstructorError(None, None, "a value that cannot be read", node.start_mark)


def _construct_mapping(loader, node, deep=False):
    first = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node, deep=deep)
        if not isinstance(key, collections.abc.Hashable):
            raise yaml.constructor.ConstructorError(None, None, "a key must be a plain name", key_node.start_mark)
        if key in first:
            raise yaml.constructor.ConstructorError(
                None, None, "a name appears twice (first on line {})".format(first[key]), key_node.start_mark)
        first[key] = key_node.start_mark.line + 1
    return yaml.SafeLoader.construct_mapping(loader, node, deep)


_GuardedLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)


class Document(collections.namedtuple("Document", "data lines open_end")):
    """A file's YAML: ``data`` (None if empty); ``lines``, ``{key path: line}`` of the keys two levels
    deep (``("waypoints",)``, ``("waypoints", "kitchen")``); ``open_end``, True when the text stops
    right after a bare value (``yaw: -0.5``, no newline, bracket or comment after it), which a write
    cut short could have ended mid-number (``-0.``) and still parse."""


# A flow bracket, or what can hide one: a quoted string, a comment.
_BRACKETS = re.compile(r"""[\[\]{}]|"(?:[^"\\]|\\.)*"|'(?:[^']|'')*'|(?:^|(?<=\s))#[^\n]*""", re.M)


def _too_deep(text):
    """The line of the first flow bracket nested past MAX_DEPTH, or None; one pass over the brackets.

    PyYAML's pure-Python scanner looks ahead over every open bracket before the composer can
    refuse the depth (quadratic: 10 KB of brackets took 125 ms and stalled the drive loop by 40 ms).
    """
    depth = 0
    for match in _BRACKETS.finditer(text):
        token = match.group()
        if token in "[{":
            depth += 1
            if depth > MAX_DEPTH:
                return text.count("\n", 0, match.start()) + 1
        elif token in "]}":
            depth = max(0, depth - 1)
    return None


def load(text):
    """The :class:`Document` of ``text``; Unreadable when it is not YAML this reader takes."""
    line = _too_deep(text)
    if line is not None:
        raise Unreadable("line {}: nested more than {} levels deep".format(line, MAX_DEPTH))
    try:
        return _compose_and_construct(text)
    except yaml.YAMLError as exc:
        raise Unreadable(describe(exc))
    except Exception as exc:  # noqa: BLE001 - hostile text: whatever the parser raises, it is unreadable
        raise Unreadable("cannot be read ({})".format(type(exc).__name__))


def _compose_and_construct(text):
    loader = _GuardedLoader(text)  # its reader refuses control characters at once
    try:
        node = loader.get_single_node()
        lines = _key_lines(loader, node)
        data = loader.construct_document(node) if node is not None else None
        return Document(data, lines, _ends_open(text, node))
    finally:
        loader.dispose()


def _ends_open(text, node):
    if text.endswith("\n"):
        return False
    while isinstance(node, (yaml.MappingNode, yaml.SequenceNode)) and node.value:
        node = node.value[-1][1] if isinstance(node, yaml.MappingNode) else node.value[-1]
    return isinstance(node, yaml.ScalarNode) and node.style is None and node.end_mark.index >= len(text.rstrip())


def _key_lines(loader, node, path=(), depth=2):
    lines = {}
    if depth and isinstance(node, yaml.MappingNode):
        for key_node, value_node in node.value:
            if isinstance(key_node, yaml.ScalarNode):
                key = path + (loader.construct_object(key_node),)
                lines[key] = key_node.start_mark.line + 1
                lines.update(_key_lines(loader, value_node, key, depth - 1))
    return lines


def describe(exc):
    """Where and what of a YAML error, as 'line 3, column 12: expected ...', without the file's text."""
    mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
    if isinstance(exc, yaml.reader.ReaderError):
        return "character {}: unacceptable character #x{:04x}: {}".format(exc.position + 1, exc.character, exc.reason)
    if not isinstance(exc, yaml.MarkedYAMLError):
        return "not valid YAML"
    what = " ".join(part for part in (exc.context, exc.problem) if part) or "not valid YAML"
    where = "line {}, column {}: ".format(mark.line + 1, mark.column + 1) if mark else ""
    return where + _QUOTED.sub(_syntax_only, what)


def _syntax_only(match):
    quoted = match.group(1)
    return match.group(0) if _SYNTAX.fullmatch(quoted) else ""


# Files read whole from a path: read() and what it needs.

_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_START = (yaml.MappingStartEvent, yaml.SequenceStartEvent)
_END = (yaml.MappingEndEvent, yaml.SequenceEndEvent)


def _cut(text, limit):
    return text if len(text) <= limit else text[:limit - 1] + "\u2026"


def read(path, max_bytes):
    """The data of the YAML file ``path``, at most ``max_bytes`` long; OSError, Unreadable."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    with os.fdopen(fd, "rb") as f:
        if not stat.S_ISREG(os.fstat(f.fileno()).st_mode):
            raise Unreadable("not a regular file")
        data = f.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise Unreadable("larger than the {} bytes such a file may have".format(max_bytes))
    try:
        return _load_bounded(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise Unreadable("not UTF-8 text") from None


def _load_bounded(text):
    """The data of YAML ``text``: anchors, aliases and nesting past READ_MAX_DEPTH refused first."""
    try:
        _check_events(text)
        return yaml.load(text, Loader=_Loader)  # noqa: S506 - a SafeLoader
    except Unreadable:
        raise
    except yaml.YAMLError as exc:  # where and what, never the file's text (it may be a link to a secret)
        raise Unreadable("not valid YAML: " + _cut(describe(exc), 200)) from None
    except Exception as exc:  # noqa: BLE001 - hostile text: whatever the parser raises, it is unreadable
        raise Unreadable("cannot be read ({})".format(type(exc).__name__)) from None


def _check_events(text):
    depth = 0
    for event in yaml.parse(text, Loader=_Loader):
        if isinstance(event, yaml.AliasEvent) or getattr(event, "anchor", None) is not None:
            raise Unreadable("anchors and aliases ('&', '*') are not allowed")
        if isinstance(event, _START):
            depth += 1
            if depth > READ_MAX_DEPTH:
                raise Unreadable("nested deeper than {} levels".format(READ_MAX_DEPTH))
        elif isinstance(event, _END):
            depth -= 1
