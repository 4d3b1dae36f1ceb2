"""Mapping a flat from the phone page, in a real browser against a real ``--sim`` server.

Start mapping from the Maps panel, drive with the joystick while the map grows on screen, save it
under a name (the page asks), and navigate on it: the saved map listed with its thumbnail, the mode
line saying which map is in use, and a press-and-drag goal on the new map that the robot reaches.
"""

import math

import pytest

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from tests.conftest import wait_for  # noqa: E402
from tests.page_browser import Browser, Finger, PageSim, canvas_box, centre, live, screenshot  # noqa: E402

MODE_JS = "(m) => {const c = document.getElementById('mode'); return c.dataset.mode === m[0] && " \
          "c.dataset.map === m[1] && c.dataset.state === 'running';}"


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_mapping"))
    yield server
    server.close()


@pytest.fixture
def page(sim):
    browser = Browser()
    page = browser.open(sim.url + "/")
    live(page)
    yield page
    assert page.errors == []
    browser.close()


def drive(page, sim, offset, hold_ms):
    """Hold the joystick ``offset`` px from its centre for ``hold_ms``, then let go."""
    x, y = centre(page, "#pad")
    finger = Finger(page, (x, y))
    finger.move((x + offset[0], y + offset[1]))
    page.wait_for_timeout(hold_ms)
    finger.lift()
    wait_for(lambda: sim.status()["motors"]["left"] == 0.0, timeout=5, message="the robot to stop on release")


def test_map_a_flat_save_it_and_navigate_on_it(sim, page):
    page.locator("#tabs button[data-tab=maps]").tap()
    page.answers.append(True)  # "Start mapping?"
    page.locator("#start-mapping").tap()
    page.wait_for_function(MODE_JS, arg=["mapping", ""], timeout=60000)
    page.wait_for_function("document.getElementById('map').dataset.imageRect", timeout=30000)
    first = page.get_attribute("#map", "data-map-version")

    page.locator("#tabs button[data-tab=drive]").tap()
    drive(page, sim, (0, -60), 1200)   # forward, out of the dock's corner
    drive(page, sim, (60, 0), 1500)    # turn on the spot: the laser sweeps the room
    page.wait_for_function("(v) => document.getElementById('map').dataset.mapVersion !== v", arg=first,
                           timeout=30000)  # the map grew on screen
    screenshot(page, "phone-mapping")
    here = sim.pose()

    page.locator("#gesture button[data-gesture=pose]").tap()  # SLAM takes no pose: refused, with the reason
    box = canvas_box(page)
    finger = Finger(page, (box["x"] + box["width"] / 2, box["y"] + box["height"] / 3))
    finger.move((box["x"] + box["width"] / 2 + 30, box["y"] + box["height"] / 3))
    finger.lift()
    page.wait_for_function("document.getElementById('error').textContent.startsWith('While mapping')")
    screenshot(page, "phone-mapping-pose")
    assert math.hypot(sim.pose()["x"] - here["x"], sim.pose()["y"] - here["y"]) < 0.05  # not moved
    page.locator("#gesture button[data-gesture=go]").tap()

    page.locator("#tabs button[data-tab=maps]").tap()
    page.answers.append("flat")  # "Save this map as:"
    page.locator("#save-map").tap()
    page.wait_for_function(MODE_JS, arg=["navigation", "flat"], timeout=60000)
    assert "navigating on flat" in page.inner_text("#mode")
    page.wait_for_selector("#maps li[data-name=flat][data-active='1'] img[src]", timeout=15000)
    page.wait_for_function("document.querySelector('#maps li[data-name=flat] img').naturalWidth > 0")
    page.wait_for_function("document.getElementById('map').dataset.imageRect && "
                           "!document.getElementById('map-note').textContent", timeout=30000)
    screenshot(page, "phone-maps")

    start = (here["x"] - 0.4 * math.cos(here["yaw"]), here["y"] - 0.4 * math.sin(here["yaw"]))  # just driven
    scale, ox, oy = (float(v) for v in page.get_attribute("#map", "data-view").split(","))
    box = canvas_box(page)
    point = (box["x"] + ox + start[0] * scale, box["y"] + oy - start[1] * scale)
    finger = Finger(page, point)
    finger.move((point[0] + 30, point[1]))
    finger.lift()
    wait_for(lambda: sim.status()["navigation"]["goal"] is not None, timeout=10, message="a goal on the new map")
    wait_for(lambda: sim.status()["navigation"]["state"] == "succeeded", timeout=60,
             message="the robot to arrive on the saved map")
    assert sim.get("/mode").json()["map"] == "flat"
