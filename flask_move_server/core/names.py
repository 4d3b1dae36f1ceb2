"""Names in the owner's language: the one rule for waypoint, map (and route) names.

A name is what a person types: letters and digits of any script ("Küche", "Kuchnia 2", "台所"),
spaces, apostrophes (' and the ’ a phone's keyboard types for "Mum's room"), and '_', '-', '.'.
It is taken in Unicode's NFC form, so "Küche" typed on a Mac (ü as u + a combining diaeresis)
and on a phone (ü as one character) is the same name, in the file and in a URL. Nothing that can
change a name's meaning in a URL or a path is allowed: no slash, backslash, '%', '?', '#', no
control or invisible character, no '..' (a path segment) and not '.' alone. :func:`same_name_key`
says when two names differ only in case or normalisation (a file system may fold them onto one
file). Pure: the standard library only.
"""

import unicodedata

from flask_move_server.core.errors import BadRequest, shown

MAX_LENGTH = 64
PUNCTUATION = "_-. '\u2019"  # the apostrophes: ' (U+0027) and ’ (U+2019)
RULE = ("1 to 64 letters, digits (of any language), spaces, apostrophes (' or \u2019), '_', '-' or '.', "
        "not starting or ending with a space, without '..' and not '.' alone, e.g. \"K\u00fcche\" or "
        "\"Mum's room\"")


def checked(name, what="name", error=BadRequest):
    """``name`` in NFC when it follows :data:`RULE`; else ``error`` saying what is wrong and what is allowed.

    ``what`` names the kind in the message ("waypoint name", "map name").
    """
    if not isinstance(name, str):
        raise error("A {} must be text, got {}.".format(what, shown(name)))
    nfc = unicodedata.normalize("NFC", name)
    problem = _problem(nfc)
    if problem:
        raise error("Invalid {} {}: {}; use {}.".format(what, shown(name), problem, RULE))
    return nfc


def same_name_key(name):
    """What two names that differ only in case or normalisation share (Unicode's caseless match)."""
    return unicodedata.normalize("NFD", unicodedata.normalize("NFD", name).casefold())


def _problem(name):
    """What breaks the rule in ``name`` (NFC), as a phrase, or None."""
    if not 1 <= len(name) <= MAX_LENGTH:
        return "it has {} characters".format(len(name))
    for index, char in enumerate(name):
        if not _allowed(char, name[index - 1] if index else None):
            return _refused(char)
    if name != name.strip(" "):
        return "it starts or ends with a space"
    if ".." in name or name == ".":
        return "'..' and '.' alone are path segments"
    return None


def _allowed(char, before):
    category = unicodedata.category(char)
    if category[0] == "L" or category == "Nd" or char in PUNCTUATION:
        return True
    # a combining mark (an accent, an Indic vowel sign) belongs to the letter or digit before it
    return category[0] == "M" and before is not None and unicodedata.category(before)[0] in "LNM"


def _refused(char):
    """Why ``char`` may not be where it is, as a phrase that shows it."""
    what = unicodedata.name(char, "").lower() or "character"
    if unicodedata.category(char)[0] == "M":
        return "the {} U+{:04X} must follow a letter".format(what, ord(char))
    if not char.isprintable():
        return "the invisible {} U+{:04X} is not allowed".format(what, ord(char))
    return "'{}' is not allowed".format(char)
