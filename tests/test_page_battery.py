"""The battery on the phone page: the top bar says the simulated robot's charge, and whether it charges.

A real browser at phone size with touch, against one real ``--sim`` server on the demo flat (the
robot starts on its dock, charging).
"""

import re

import pytest

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from tests.page_browser import PageSim, live, screenshot  # noqa: E402


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_battery"), extra_config="  battery_start: 0.6\n")
    yield server
    server.close()


@pytest.fixture
def page(sim, browser):
    page = browser.open(sim.url + "/")
    live(page)
    yield page
    assert page.errors == []
    page.close()


def _shown_percent(page):
    match = re.fullmatch(r"(\d+)\u202f%", page.locator("#battery-text").text_content())
    assert match, page.locator("#battery-text").text_content()
    return int(match.group(1))


def _put_dock(sim, x, y):
    import requests

    r = requests.put(sim.url + "/waypoints/dock", json={"x": x, "y": y, "yaw": 0.0}, headers=sim.headers(), timeout=10)
    assert r.status_code in (200, 201), r.text


def test_the_top_bar_says_the_charge_and_whether_it_charges(sim, page):
    _put_dock(sim, 8.4, 0.9)  # the dock moved to the kitchen: the robot stands off it, its battery draining
    page.wait_for_function("document.getElementById('battery').dataset.charging === '0'", timeout=10000)
    battery = sim.status()["battery"]
    assert battery["charging"] is False
    assert abs(_shown_percent(page) - battery["percentage"]) <= 1.5  # told when it moved a whole point
    assert not page.locator("#battery-bolt").is_visible()
    assert page.get_attribute("#battery", "aria-label") == "Battery {}\u202f%".format(_shown_percent(page))
    mode, chip, conn = (page.locator(selector).bounding_box() for selector in ("#mode", "#battery", "#conn"))
    assert mode["x"] + mode["width"] <= chip["x"] and chip["x"] + chip["width"] <= conn["x"], "between, not over"
    assert page.evaluate("(e => e.scrollWidth <= e.clientWidth)(document.getElementById('mode'))"), \
        "the mode keeps its whole name beside the battery on a 390 px phone"
    page.locator("#battery").tap()  # a phone has no hover: a tap says it in words
    page.wait_for_function("document.getElementById('hint').textContent.startsWith('Battery ')")

    _put_dock(sim, 0.0, 0.0)  # the dock under the robot again: it charges
    page.wait_for_function("document.getElementById('battery').dataset.charging === '1'", timeout=10000)
    assert page.locator("#battery-bolt").is_visible()
    words = page.get_attribute("#battery", "aria-label")
    assert re.fullmatch(r"Battery \d+\u202f%, charging", words), words
    assert page.evaluate("(e => e.scrollWidth <= e.clientWidth)(document.getElementById('mode'))")
    page.locator("#battery").tap()
    page.wait_for_function("document.getElementById('hint').textContent.endsWith(', charging')")
    screenshot(page, "phone-battery")
    before = _shown_percent(page)
    page.wait_for_function("Number(document.getElementById('battery-text').textContent.split('\u202f')[0]) > {}"
                           .format(before), timeout=15000)  # told a point at a time as it charges
