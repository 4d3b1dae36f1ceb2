"""Where the robot is, on the phone page: the position the robot assumed after a map switch.

After a switch to a map the robot sets its position to the map's dock wherever it stands; the
page says so in a banner ("Position assumed: dock — check it") until the owner confirms it or
sets the position on the map. With no map in use (idle), the grey robot's note says so instead
of blaming localisation. Real ``--sim`` server, Debian's chromium at phone size with touch.
"""

import math
import shutil

import pytest

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from tests.conftest import ROOT, wait_for  # noqa: E402
from tests.page_browser import DEMO_WAYPOINTS, DESKTOP, PHONE, Finger, PageSim, live, screenshot  # noqa: E402

LANDSCAPE = dict(PHONE, viewport={"width": 844, "height": 390})
BANNER_SHOWN = "!document.getElementById('whereabouts').hidden"
BANNER_GONE = "document.getElementById('whereabouts').hidden"


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    folder = tmp_path_factory.mktemp("page_whereabouts")
    maps = folder / "maps"
    maps.mkdir()
    for ext in ("yaml", "pgm"):
        shutil.copy("{}/config/maps/demo.{}".format(ROOT, ext), str(maps / "demo.{}".format(ext)))
    shutil.copy(DEMO_WAYPOINTS, str(maps / "demo.waypoints.yaml"))  # its dock at the origin
    server = PageSim(folder)
    yield server
    server.close()


def open_page(browser, sim, device=None):
    page = browser.open(sim.url + "/", **({"device": device} if device else {}))
    live(page)
    return page


def use_the_demo_map(sim):
    r = sim.post("/mode", {"mode": "navigation", "map": "demo", "wait": 60}, timeout=90)
    assert r.status_code == 200 and r.json()["localization"]["assumed"] is True, r.text


def assumed(sim):
    return sim.get("/mode").json()["localization"]["assumed"]


def test_after_a_map_switch_the_page_asks_to_check_the_position(sim, browser):
    page = open_page(browser, sim)
    page.wait_for_function("document.getElementById('mode').dataset.state === 'running'")
    assert page.locator("#whereabouts").is_hidden()  # the demo's own map: nothing assumed
    use_the_demo_map(sim)
    page.wait_for_function(BANNER_SHOWN, timeout=15000)
    assert page.inner_text("#whereabouts-text") == "Position assumed: dock — check it"
    assert page.locator("#pose-right").is_visible() and page.locator("#pose-set").is_visible()
    page.wait_for_function("document.getElementById('map').dataset.imageRect")
    screenshot(page, "phone-position-assumed")
    assert page.errors == []


@pytest.mark.parametrize("device,name", [(LANDSCAPE, "landscape-position-assumed"),
                                         (DESKTOP, "desktop-position-assumed")])
def test_the_banner_fits_on_its_side_and_on_a_desktop(sim, browser, device, name):
    if not assumed(sim):
        use_the_demo_map(sim)
    page = open_page(browser, sim, device)
    page.wait_for_function(BANNER_SHOWN, timeout=15000)
    page.wait_for_function("document.getElementById('map').dataset.imageRect")
    for button in ("#pose-right", "#pose-set", "#stop"):
        box = page.locator(button).bounding_box()
        assert box and box["y"] + box["height"] <= device["viewport"]["height"], button
    assert page.locator("#map").bounding_box()["height"] >= 150, "room for the map"
    screenshot(page, name)
    assert page.errors == []


def test_its_right_confirms_the_position_and_the_banner_goes(sim, browser):
    if not assumed(sim):
        use_the_demo_map(sim)
    page = open_page(browser, sim)
    page.wait_for_function(BANNER_SHOWN, timeout=15000)
    before = sim.pose()
    page.locator("#pose-right").tap()
    page.wait_for_function(BANNER_GONE, timeout=10000)
    wait_for(lambda: not assumed(sim), message="the robot to hear it is right")
    assert math.hypot(sim.pose()["x"] - before["x"], sim.pose()["y"] - before["y"]) < 0.01  # nothing moved
    assert page.errors == []


def test_set_position_then_a_press_on_the_map_sets_it_and_the_banner_goes(sim, browser):
    use_the_demo_map(sim)
    page = open_page(browser, sim)
    page.wait_for_function(BANNER_SHOWN, timeout=15000)
    page.locator("#pose-set").tap()
    assert page.get_attribute("#map", "data-gesture") == "pose"
    assert "where the robot really is" in page.inner_text("#hint")
    page.wait_for_function("document.getElementById('map').dataset.imageRect")
    box = page.locator("#map").bounding_box()
    start = (box["x"] + box["width"] * 0.5, box["y"] + box["height"] * 0.5)
    finger = Finger(page, start)
    for step in range(1, 6):
        finger.move((start[0] + 8 * step, start[1]))
    finger.lift()
    page.wait_for_function(BANNER_GONE, timeout=10000)
    wait_for(lambda: not assumed(sim), message="the set position to end the assumption")
    page.wait_for_function("document.getElementById('map').dataset.gesture === 'go'")  # back to Go after one
    assert page.errors == []


def test_with_no_map_in_use_the_grey_robot_says_so(sim, browser):
    page = open_page(browser, sim)
    page.wait_for_function("document.getElementById('map').dataset.robotPx")
    r = sim.post("/mode", {"mode": "idle", "wait": 30}, timeout=60)
    assert r.status_code == 200, r.text
    page.wait_for_function("document.getElementById('stale-note').textContent.startsWith('no map in use')",
                           timeout=15000)
    assert "stalled" not in page.inner_text("#stale-note")
    assert page.locator("#whereabouts").is_hidden()
    screenshot(page, "phone-idle")
    assert page.errors == []
