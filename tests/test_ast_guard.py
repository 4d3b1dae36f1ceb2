"""ast.parse from several threads at once, with the garbage collector running Python mid-parse.

On CPython 3.11 (Debian bookworm's Python) this raised ``SystemError: AST constructor recursion
depth mismatch`` now and then, and did so once while the test suite made an app (werkzeug parses
each route) as a ROS thread logged a traceback. Other versions pass with or without the guard.
"""

import ast
import gc
import sys
import threading
import time

import flask_move_server.web  # noqa: F401  (making apps is what installs the guard)
from flask_move_server.process import ast_guard

SOURCE = "\n".join("x{0} = [{0}, ({0}, {0}), {{'a': {0}}}]".format(i) for i in range(200))


class Finalised:
    def __del__(self):
        sum(range(50))  # Python run by the collector: a point where another thread may take over


def test_parsing_in_several_threads_at_once_never_raises():
    errors, stop = [], threading.Event()

    def parse():
        while not stop.is_set():
            try:
                ast.parse(SOURCE)
            except SystemError as exc:
                errors.append(exc)

    def make_garbage():
        while not stop.is_set():
            cycle = Finalised()
            cycle.me = cycle

    switch, threshold = sys.getswitchinterval(), gc.get_threshold()
    sys.setswitchinterval(1e-6)
    gc.set_threshold(50, 1, 1)
    threads = [threading.Thread(target=parse) for _ in range(4)] + [threading.Thread(target=make_garbage)]
    try:
        for thread in threads:
            thread.start()
        time.sleep(4)  # unguarded, 3.11 fails about once a second here
    finally:
        stop.set()
        for thread in threads:
            thread.join()
        sys.setswitchinterval(switch)
        gc.set_threshold(*threshold)
    assert errors == []


def test_the_guard_is_installed_once_and_only_where_needed():
    ast_guard.serialise_ast_parse()
    guarded = getattr(ast.parse, "serialised", False)
    assert guarded == (sys.version_info[:2] == ast_guard.AFFECTED)
    if guarded:
        assert not getattr(ast.parse.__wrapped__, "serialised", False), "wrapped twice"
