"""Zones on the phone page (Chromium at 390 × 844, touch) against a real ``--sim`` server.

The owner draws a no-go area by tapping its corners on the map and a wall by tapping its ends,
names each, switches one off and deletes it, moves and deletes corners of a saved one, and is
told when a place marked lies in a zone; the server's zones (``GET /zones``, what the
costmaps are sent) follow, and the map draws them. Where a tap lands is computed from the
server's own map metadata and the image rectangle the page drew (tests/test_page.py ``Screen``).
"""

import math

import pytest

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from tests.conftest import wait_for  # noqa: E402
from tests.page_browser import Finger, PageSim, on_the_map, screenshot  # noqa: E402
from tests.test_page import Screen, on_page  # noqa: E402

CORNERS = [(1.5, 0.0), (2.5, 0.0), (2.5, 1.3), (1.5, 1.3)]  # across the way from the dock to the kitchen
WALL = [(4.8, 2.5), (6.1, 2.5)]  # across the bedroom's door


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_zones"))
    yield server
    server.close()


@pytest.fixture
def page(sim, browser):
    page = on_the_map(browser, sim)
    yield page
    assert page.errors == []
    page.close()


def _draw(page, sim, button, points, name):
    page.locator("#tabs button[data-tab=places]").tap()
    page.locator(button).tap()
    assert page.get_attribute("#map", "data-gesture") == "zone"
    assert page.locator("#zone-save").is_disabled() and page.locator("#zone-start").is_hidden()
    assert page.locator("#zone-save").is_visible()
    screen = Screen(page, sim)
    for x, y in points:
        page.touchscreen.tap(*on_page(page, screen.screen(x, y)))
    page.wait_for_function("!document.getElementById('zone-save').disabled")
    page.answers.append(name)
    page.locator("#zone-save").tap()
    page.wait_for_selector('#zones li[data-name="{}"]'.format(name))
    assert page.get_attribute("#map", "data-gesture") == "go"  # a tap on the map sends the robot again
    return screen


def test_draw_a_no_go_area_and_a_wall_switch_one_off_and_delete_it(sim, page):
    screen = _draw(page, sim, "#zone-keepout", CORNERS, "Katzenecke")
    zone = sim.get("/zones/Katzenecke").json()
    assert zone["kind"] == "keepout" and zone["enabled"] is True
    for (x, y), (zx, zy) in zip(CORNERS, zone["polygon"]):
        assert math.hypot(x - zx, y - zy) <= screen.tolerance, (CORNERS, zone["polygon"])
    assert "no-go, on" in page.inner_text('#zones li[data-name="Katzenecke"]')
    screenshot(page, "zones-drawn")

    _draw(page, sim, "#zone-wall", WALL, "Treppe")
    assert sim.get("/zones/Treppe").json()["kind"] == "wall"

    keep_out = page.locator('#zones li[data-name="Katzenecke"] button', has_text="Keep out")
    assert keep_out.get_attribute("aria-pressed") == "true"
    keep_out.tap()
    wait_for(lambda: sim.get("/zones/Katzenecke").json()["enabled"] is False, message="the zone switched off")
    page.wait_for_function("document.querySelector('#zones li[data-name=Katzenecke]').textContent.includes('off')")
    assert keep_out.get_attribute("aria-pressed") == "false"

    page.answers.append(True)  # "Delete the zone Treppe?"
    page.locator('#zones li[data-name="Treppe"] button', has_text="Delete").tap()
    page.wait_for_selector('#zones li[data-name="Treppe"]', state="detached")
    assert [z["name"] for z in sim.get("/zones").json()["zones"]] == ["Katzenecke"]
    assert page.asked[-1] == "Delete the zone Treppe?"


def test_a_zone_drawn_wrong_says_why_and_nothing_is_saved(sim, page):
    page.locator("#tabs button[data-tab=places]").tap()
    page.locator("#zone-keepout").tap()
    screen = Screen(page, sim)
    for x, y in [(1.0, 3.0), (2.0, 4.0), (2.0, 3.0), (1.0, 4.0)]:  # a bow tie: it crosses itself
        page.touchscreen.tap(*on_page(page, screen.screen(x, y)))
    page.answers.append("Knoten")
    page.locator("#zone-save").tap()
    page.wait_for_function("document.getElementById('error').textContent.includes('crosses itself')")
    assert sim.get("/zones/Knoten").status_code == 404
    assert not page.locator("#zone-draw").is_hidden()  # still drawing: Undo and tap again, or Cancel
    page.locator("#zone-undo").tap()
    page.locator("#zone-cancel").tap()
    assert page.get_attribute("#map", "data-gesture") == "go"


def _tap(page, screen, x, y):
    page.touchscreen.tap(*on_page(page, screen.screen(x, y)))


def test_edit_a_saved_zone_move_one_corner_delete_another_and_it_stays_off(sim, page):
    square = [[1.5, 3.0], [2.5, 3.0], [2.5, 4.0], [1.5, 4.0]]  # in the office
    assert sim.put("/zones/Teppich", {"kind": "keepout", "polygon": square, "enabled": False}).status_code == 201
    page.locator("#tabs button[data-tab=places]").tap()
    page.locator('#zones li[data-name="Teppich"] button', has_text="Edit").tap()
    assert page.get_attribute("#map", "data-gesture") == "zone"
    assert "Teppich" in page.inner_text("#zone-hint") and page.locator("#zone-corner").is_hidden()
    screen = Screen(page, sim)
    _tap(page, screen, 2.5, 4.0)  # picks corner 3
    page.wait_for_function("document.getElementById('zone-hint').textContent.includes('corner 3 goes')")
    _tap(page, screen, 2.8, 4.3)  # ... and puts it there
    _tap(page, screen, 1.5, 4.0)  # picks corner 4
    page.wait_for_function("!document.getElementById('zone-corner').hidden")
    screenshot(page, "zones-editing")
    page.locator("#zone-corner").tap()
    page.wait_for_function("document.getElementById('zone-corner').hidden")
    page.locator("#zone-save").tap()
    page.wait_for_function("document.getElementById('zone-draw').hidden")
    zone = sim.get("/zones/Teppich").json()
    assert zone["enabled"] is False, "editing its corners switched it on"
    assert len(zone["polygon"]) == 3
    for (x, y), (zx, zy) in zip([(1.5, 3.0), (2.5, 3.0), (2.8, 4.3)], zone["polygon"]):
        assert math.hypot(x - zx, y - zy) <= screen.tolerance, zone["polygon"]
    assert not page.asked, "an edited zone keeps its name: nothing is asked"
    assert sim.delete("/zones/Teppich").status_code == 204


def test_a_place_marked_in_a_no_go_area_is_kept_and_the_page_says_so(sim, page):
    r = sim.put("/zones/Napfecke", {"kind": "keepout", "polygon": [list(c) for c in CORNERS]})
    assert r.status_code in (200, 201), r.text
    page.locator("#tabs button[data-tab=places]").tap()
    page.locator("#gesture button[data-gesture=mark]").tap()
    screen = Screen(page, sim)
    page.answers.append("Napf")
    start = screen.screen(2.0, 0.6)
    finger = Finger(page, on_page(page, start))
    finger.move(on_page(page, (start[0] + 40, start[1])))
    finger.lift()
    page.wait_for_selector('#places li[data-name="Napf"]')
    page.wait_for_function("document.getElementById('done').textContent.includes('lies in a no-go zone')")
    assert sim.get("/waypoints/Napf").status_code == 200
    assert sim.delete("/waypoints/Napf").status_code == 204
    assert sim.delete("/zones/Napfecke").status_code == 204
