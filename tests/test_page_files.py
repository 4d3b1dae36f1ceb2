"""The phone page's files: light, self-contained, open without a token, and served as modules.

No browser here (tests/test_page*.py drive one), so ``make test-debian`` runs these too: what the
files promise that a plain check can hold. The app is the real one over tests/fake_robot.py.
"""

import os
import re

import pytest

from flask_move_server.web import create_app
from tests.fake_robot import FakeRobot

STATIC = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "flask_move_server", "web",
                      "static")
FILES = sorted(os.path.relpath(os.path.join(d, f), STATIC) for d, _, names in os.walk(STATIC) for f in names)
BUDGET = 160 * 1024  # issue 13: everything but the map image; issue 36 (zones) took it past 150 KiB (gzip: issue 37)


@pytest.fixture
def robot():
    return FakeRobot()


@pytest.fixture
def client(robot_config, robot, store):
    return create_app(robot_config, robot, store, token="s3cret").test_client()


def test_the_page_is_light():
    assert sum(os.path.getsize(os.path.join(STATIC, f)) for f in FILES) <= BUDGET


@pytest.mark.parametrize("name", FILES)
def test_nothing_is_fetched_from_elsewhere(name):
    """No CDN, no font service, no absolute URL: the robot's network may have no internet at all."""
    with open(os.path.join(STATIC, name), encoding="utf-8") as f:
        text = f.read()
    assert not re.search(r"(https?:)?//[a-z0-9.-]+\.[a-z]{2,}/", text, re.I), name
    assert "@import url(" not in text, name


def test_every_module_the_page_imports_is_served_without_a_token_as_javascript(client):
    page = client.get("/")
    assert page.status_code == 200 and page.mimetype == "text/html"
    html = page.get_data(as_text=True)
    modules = set(re.findall(r'src="(/static/js/[\w.]+\.js)"', html) + re.findall(r'href="(/static/js/[\w.]+)"', html))
    for name in [f for f in FILES if f.endswith(".js")]:
        with open(os.path.join(STATIC, name), encoding="utf-8") as f:
            modules.update("/static/js/" + m for m in re.findall(r'from "\./([\w.]+\.js)"', f.read()))
    assert {"/static/js/main.js", "/static/js/live.js", "/static/js/mapview.js"} <= modules
    for path in sorted(modules):
        r = client.get(path)
        assert r.status_code == 200, path
        assert r.mimetype in ("text/javascript", "application/javascript"), (path, r.mimetype)
    assert client.get("/waypoints").status_code == 401, "the page is open, the API is not"
