"""One thread at a time in ``ast.parse`` on Python 3.11, whose AST builder is not thread-safe.

CPython 3.11 keeps the AST builder's recursion depth in state shared by every thread. When the
garbage collector runs Python code in the middle of a parse (a finalizer) and another thread
parses meanwhile, the check at the end fails with ``SystemError: AST constructor recursion depth
mismatch`` (python/cpython#106905; 3.8-3.10 and 3.12+ do not have it). In this server two
threads do parse at once: werkzeug compiles each route's URL builder with ``ast.parse`` when an
app is made, and Python 3.11's ``traceback`` parses source lines for its carets whenever a ROS
thread logs a traceback. Debian bookworm and Raspberry Pi OS ship 3.11, so an app made while
rospy logs a connection error could fail to start (seen once in the test suite).

:func:`serialise_ast_parse` wraps ``ast.parse`` in a re-entrant lock (a finalizer run mid-parse
may itself format a traceback in the same thread). Idempotent; does nothing on other versions.
Called by the modules that make apps and start ROS threads.
"""

import ast
import functools
import sys
import threading

AFFECTED = (3, 11)


def serialise_ast_parse():
    """Make ``ast.parse`` take one thread at a time, on Python 3.11 only."""
    if sys.version_info[:2] != AFFECTED or getattr(ast.parse, "serialised", False):
        return
    parse, lock = ast.parse, threading.RLock()

    @functools.wraps(parse)
    def serialised_parse(*args, **kwargs):
        with lock:
            return parse(*args, **kwargs)

    serialised_parse.serialised = True
    ast.parse = serialised_parse
