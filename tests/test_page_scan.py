"""What owners of other robot apps miss, on the phone page: the laser scan and the trail on the map
(Vizanti, ROSboard), a joystick speed setting with a slow mode (ros2d-quasar), a Home button (Valetudo).

A real browser at phone size with touch, against one real ``--sim`` server on the demo flat.
"""

import json

import pytest
import yaml

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from flask_move_server.ros.scan import RATE  # noqa: E402
from tests.conftest import wait_for  # noqa: E402
from tests.page_browser import DESKTOP, PHONE, Finger, PageSim, RequestLog, centre, live, screenshot  # noqa: E402

LANDSCAPE = dict(PHONE, viewport={"width": 844, "height": 390})


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_scan"))
    yield server
    server.close()


@pytest.fixture
def page(sim, browser):
    page = browser.open(sim.url + "/")
    live(page)
    yield page
    assert page.errors == []
    page.close()


def canvas(page, key):
    return page.get_attribute("#map", "data-" + key)


def scan_drawn(page):
    page.wait_for_function("Number(document.getElementById('map').dataset.scanPoints) > 20", timeout=20000)


def hold_stick(page, sim, log, offset=(0, -90), beats=4):
    """Push the joystick to ``offset`` px until ``beats`` commands went, let go; the /teleop bodies sent."""
    before = len(log.calls("POST", "/teleop"))
    x, y = centre(page, "#pad")
    finger = Finger(page, (x, y))
    finger.move((x + offset[0], y + offset[1]))
    wait_for(lambda: len(log.calls("POST", "/teleop")) >= before + beats, timeout=10, message="teleop commands")
    finger.lift()
    wait_for(lambda: sim.status()["motors"]["left"] == 0.0, timeout=10, message="the robot to stop on release")
    return [json.loads(r.post_data) for r in log.calls("POST", "/teleop")[before:]]


def test_the_scan_is_drawn_at_a_few_updates_a_second_and_can_be_hidden(sim, page):
    scan_drawn(page)
    seen, started = page.evaluate("[Number(document.getElementById('map').dataset.scanSeen), performance.now()]")
    page.wait_for_timeout(3000)
    now_seen, now = page.evaluate("[Number(document.getElementById('map').dataset.scanSeen), performance.now()]")
    assert 1 <= now_seen - seen <= (now - started) / 1000 * RATE + 2, "scans told at most RATE times a second"
    screenshot(page, "phone-scan")

    page.locator("#scan-toggle").tap()
    page.wait_for_function("document.getElementById('map').dataset.scanPoints === '0'")
    assert page.get_attribute("#scan-toggle", "aria-pressed") == "false"
    page.reload()  # the choice is kept on this phone
    live(page)
    page.wait_for_function("Number(document.getElementById('map').dataset.scanSeen) > 1")
    assert canvas(page, "scan-points") == "0", "scans arrive, hidden"
    page.locator("#scan-toggle").tap()
    scan_drawn(page)


def test_the_trail_follows_where_the_robot_drove(sim, page):
    log = RequestLog(page)
    assert canvas(page, "trail-points") in ("0", "1")
    hold_stick(page, sim, log, offset=(0, -90), beats=8)
    hold_stick(page, sim, log, offset=(80, -40), beats=8)
    page.wait_for_function("Number(document.getElementById('map').dataset.trailPoints) >= 3")
    screenshot(page, "phone-trail")


def test_slow_mode_sends_smaller_commands_and_is_remembered(sim, page):
    log = RequestLog(page)
    assert "max 0.40" in page.locator("#speed-text").text_content()  # the robot's own limit (teleop.max_linear)
    fast = max(body["linear"] for body in hold_stick(page, sim, log))
    assert fast == pytest.approx(0.4, abs=0.02)

    page.locator("#slow").tap()
    slow = max(body["linear"] for body in hold_stick(page, sim, log))
    assert 0 < slow <= 0.11, "slow mode drives at a quarter of the robot's limit"
    assert page.locator("#speed-range").is_disabled()

    page.reload()
    live(page)
    assert page.get_attribute("#slow", "aria-pressed") == "true"
    assert "0.10 m/s" in page.locator("#speed-text").text_content()


def test_the_speed_setting_scales_the_joystick(sim, page):
    log = RequestLog(page)
    page.locator("#speed-range").fill("50")
    half = max(body["linear"] for body in hold_stick(page, sim, log))
    assert half == pytest.approx(0.2, abs=0.02)
    assert "0.20 m/s" in page.locator("#speed-text").text_content()
    page.locator("#speed-range").fill("100")


def test_home_docks_onto_the_charger_whatever_its_name_and_without_a_dock_says_why(sim, page):
    log = RequestLog(page)
    sim.post("/goto", {"x": 1.0, "y": 0.5, "yaw": 0.0, "wait": 30}, timeout=40)  # away from the dock
    assert page.get_attribute("#home", "aria-disabled") == "false"
    page.locator("#home").tap()
    wait_for(lambda: log.calls("POST", "/dock"), timeout=5, message="a docking asked for")
    assert "valid_until" in json.loads(log.calls("POST", "/dock")[0].post_data)  # late on a bad Wi-Fi: refused
    page.wait_for_function("document.getElementById('nav-text').textContent === 'Going home to dock.'")
    page.wait_for_function("document.getElementById('home').textContent === 'Charging'", timeout=60000)
    assert page.get_attribute("#home", "aria-pressed") == "true"
    assert page.locator("#nav-text").text_content() == "Charging at dock."
    # the battery's own reading (1 a second) says it charges: on a loaded machine a moment after the dock's state
    page.wait_for_function("document.getElementById('battery').dataset.charging === '1'", timeout=10000)
    sim.post("/goto", {"x": 1.0, "y": 0.5, "yaw": 0.0, "wait": 30}, timeout=40)  # off the charger first, by itself
    page.wait_for_function("document.getElementById('home').textContent === 'Home'")

    dock = sim.get("/waypoints/dock").json()
    charger = {"x": dock["x"], "y": dock["y"], "yaw": dock["yaw"], "dock": True}
    assert sim_request(sim, "PUT", "/waypoints/Ladestation", charger).status_code == 201  # the owner's word
    try:
        assert sim_request(sim, "DELETE", "/waypoints/dock").status_code == 204  # the old name goes: no matter
        page.wait_for_function("document.getElementById('home').title.endsWith('Ladestation')")
        page.locator("#home").tap()
        wait_for(lambda: len(log.calls("POST", "/dock")) == 2, timeout=5, message="a second docking asked for")
        page.wait_for_function("document.getElementById('nav-text').textContent === 'Going home to Ladestation.'")
        sim.post("/stop")
        assert sim_request(sim, "DELETE", "/waypoints/Ladestation").status_code == 204
        page.wait_for_function("document.getElementById('home').getAttribute('aria-disabled') === 'true'")
        page.locator("#home").tap(force=True)  # greyed (aria-disabled), yet a finger can tap it: to learn why
        page.wait_for_function("document.getElementById('error').textContent.includes('no charger marked')")
        assert len(log.calls("POST", "/dock")) == 2, "no docking without a dock"
    finally:
        body = {"x": dock["x"], "y": dock["y"], "yaw": dock["yaw"]}
        assert sim_request(sim, "PUT", "/waypoints/dock", body).status_code in (200, 201)
    page.wait_for_function("document.getElementById('home').getAttribute('aria-disabled') === 'false'")


def test_places_shows_the_charger_and_the_owner_chooses_another_in_their_words(sim, page):
    charger = "Ladestation Küche"
    dock = sim.get("/waypoints/dock").json()
    here = {"x": dock["x"], "y": dock["y"], "yaw": dock["yaw"]}
    assert sim_request(sim, "PUT", "/waypoints/" + charger, here).status_code == 201
    try:
        page.locator("#tabs button[data-tab=places]").tap()
        row = '#places li[data-name="{}"] button[title=Charger]'
        page.wait_for_selector(row.format(charger), timeout=10000)
        assert page.get_attribute(row.format("dock"), "aria-pressed") == "true"  # the charger, shown
        assert page.get_attribute(row.format(charger), "aria-pressed") == "false"
        page.locator(row.format(charger)).tap()
        page.wait_for_function("document.getElementById('home').title === 'Dock at Ladestation Küche'")
        assert sim.get("/waypoints/" + charger).json().get("dock") is True  # saved by the server
        assert "dock" not in sim.get("/waypoints/dock").json()  # the one before lost it
        page.wait_for_selector(row.format(charger) + '[aria-pressed="true"]', timeout=5000)
        assert page.get_attribute(row.format("dock"), "aria-pressed") == "false"
        with open(sim.status()["waypoints"]["file"], encoding="utf-8") as saved:
            assert yaml.safe_load(saved)["dock"] == charger  # in the file, in the owner's words
    finally:
        assert sim_request(sim, "PUT", "/waypoints/dock", dict(here, dock=True)).status_code == 200
        assert sim_request(sim, "DELETE", "/waypoints/" + charger).status_code == 204
        page.locator("#tabs button[data-tab=drive]").tap()


def sim_request(sim, method, path, body=None):
    import requests

    return requests.request(method, sim.url + path, json=body, headers=sim.headers(), timeout=10)


@pytest.mark.parametrize("device, name", [(LANDSCAPE, "phone-landscape-scan"), (DESKTOP, "desktop-scan")])
def test_pictures_of_the_scan_on_the_saved_map(sim, browser, device, name):
    page = browser.open(sim.url + "/", device=device)
    live(page)
    scan_drawn(page)
    screenshot(page, name)
    page.close()


def test_the_scan_while_mapping_shows_the_walls_not_yet_on_the_map(sim, browser, page):
    """The last test: it leaves the server mapping."""
    log = RequestLog(page)
    hold_stick(page, sim, log, offset=(0, -90), beats=8)
    page.wait_for_function("Number(document.getElementById('map').dataset.trailPoints) >= 2")
    assert sim.post("/mode", {"mode": "mapping", "wait": 60}, timeout=70).status_code == 200
    page.wait_for_function("Number(document.getElementById('map').dataset.trailPoints) <= 1")  # the old map's trail
    scan_drawn(page)
    screenshot(page, "phone-mapping-scan")
    for device, name in ((LANDSCAPE, "phone-landscape-mapping-scan"), (DESKTOP, "desktop-mapping-scan")):
        other = browser.open(sim.url + "/", device=device)
        live(other)
        other.wait_for_function("document.getElementById('map').dataset.imageRect", timeout=30000)
        scan_drawn(other)
        screenshot(other, name)
        other.close()
