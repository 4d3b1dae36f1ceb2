"""The VDA 5050 JSON schemas, as a registry package bundles them (PyPI ``vda5050-sdk``, pinned in setup.py).

It bundles the 2.1.0 schemas; 2.0.0's differ, for the fields this robot sends, in one requirement
2.1.0 dropped, checked here by hand (``stricter_in_2_0``). ``check(kind, message)`` raises
AssertionError naming the first fields that break them.
"""

import functools
import importlib.util
import json
import os

import pytest

jsonschema = pytest.importorskip("jsonschema")
# The package's files only: importing it would need its own dependencies (pydantic), which the schemas do not.
_SDK = importlib.util.find_spec("vda5050")
if _SDK is None:
    pytest.skip("vda5050-sdk is not installed (pip install -e '.[test]'; it needs Python 3.10+)",
                allow_module_level=True)
SCHEMAS = os.path.join(_SDK.submodule_search_locations[0], "validation", "schemas")

KINDS = ("order", "instantActions", "state", "visualization", "connection", "factsheet")


@functools.lru_cache(maxsize=None)
def validator(kind):
    with open(os.path.join(SCHEMAS, kind + ".json"), encoding="utf-8") as f:
        schema = json.load(f)
    return jsonschema.Draft202012Validator(schema, format_checker=jsonschema.FormatChecker())


def problems(kind, message):
    """What breaks ``kind``'s schema in ``message``, or a 2.0.0 rule 2.1.0 dropped: a list of sentences
    (empty when it is valid)."""
    found = ["{}: {}".format("/".join(str(p) for p in e.absolute_path) or "(top)", e.message)
             for e in validator(kind).iter_errors(message)]
    return found + stricter_in_2_0(kind, message)


def stricter_in_2_0(kind, message):
    """The one requirement of the 2.0.0 schemas that 2.1.0's no longer make, among the fields this robot
    sends (found by comparing every ``required`` and ``enum`` of the two sets): a node state's
    ``nodePosition`` has a ``theta``."""
    if kind != "state":
        return []
    return ["nodeStates/{}/nodePosition: 'theta' is a required property (2.0.0)".format(i)
            for i, node in enumerate(message.get("nodeStates", []))
            if "nodePosition" in node and "theta" not in node["nodePosition"]]


def check(kind, message):
    found = problems(kind, message)
    assert not found, "{} message breaks the VDA 5050 schema: {}".format(kind, "; ".join(found[:5]))
