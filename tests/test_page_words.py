"""What the page's status line and refusals say, in a real browser against a real ``--sim`` server.

A person reads the line under the top bar to know what the robot does: it must not go stale (an
"arrived at sofa" from before a map switch, "cancelled" while they drive with the joystick, an
"idle" that hides a trip a restart cut short), and a refusal must say which button to press, not
which endpoint to POST to.
"""

import pytest

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from tests.conftest import wait_for  # noqa: E402
from tests.page_browser import Finger, PageSim, centre, live, screenshot  # noqa: E402
from tests.test_page import at_rest  # noqa: E402

API_WORDS = ("POST ", "GET /", "PUT /", "robotctl", "curl")


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    holder = {"sim": PageSim(tmp_path_factory.mktemp("page_words"))}
    yield holder
    holder["sim"].close()


@pytest.fixture(scope="module")
def page(server, browser):
    page = browser.open(server["sim"].url + "/")
    live(page)
    return page


def nav_text(page):
    return page.inner_text("#nav-text")


def test_driving_with_the_joystick_is_not_called_cancelled(server, page):
    sim = server["sim"]
    at_rest(sim)
    assert sim.post("/goto", {"name": "kitchen"}).status_code == 202
    page.wait_for_function("document.getElementById('nav').dataset.state === 'active'", timeout=10000)
    x, y = centre(page, "#pad")
    finger = Finger(page, (x, y))
    finger.move((x, y - 40))
    try:
        page.wait_for_function("document.getElementById('nav-text').textContent === 'driving with the joystick'",
                               timeout=5000)
    finally:
        finger.lift()
    wait_for(lambda: sim.status()["motors"]["left"] == 0.0, timeout=5, message="the robot to stop on release")


def test_an_arrival_is_not_told_on_the_next_map(server, page):
    sim = server["sim"]
    at_rest(sim)
    r = sim.post("/goto", {"name": "sofa", "wait": 60}, timeout=70)
    assert r.status_code == 200, r.text
    page.wait_for_function("document.getElementById('nav-text').textContent === 'arrived at sofa'", timeout=5000)
    assert sim.post("/mode", {"mode": "mapping", "wait": 60}, timeout=70).status_code == 200
    page.wait_for_function("document.getElementById('mode').dataset.mode === 'mapping'", timeout=10000)
    page.wait_for_function("document.getElementById('nav').dataset.state === 'idle'", timeout=5000)
    assert "sofa" not in nav_text(page)
    assert sim.status()["navigation"]["state"] == "idle"
    assert sim.post("/mode", {"mode": "navigation", "map": "demo", "wait": 60}, timeout=70).status_code == 200


def test_a_goal_a_switch_gave_up_is_said_without_api_words_and_the_map_stays_put(server, page):
    """The new owner's walk: "…Send it again once GET /mode says running." on a line that grew to four
    and dropped the map by 55 px under a finger aiming at it."""
    sim = server["sim"]
    at_rest(sim)
    top = page.locator("#map").bounding_box()["y"]
    assert sim.post("/goto", {"name": "kitchen"}).status_code == 202
    page.wait_for_function("document.getElementById('nav').dataset.state === 'active'", timeout=10000)
    assert page.locator("#map").bounding_box()["y"] == top, "Cancel showing moves nothing"
    assert sim.post("/mode", {"mode": "mapping", "wait": 60}, timeout=70).status_code == 200
    page.wait_for_function("document.getElementById('nav').dataset.state === 'aborted'", timeout=10000)
    said = nav_text(page)
    assert said.startswith("failed: The robot switched to mapping") and not any(w in said for w in API_WORDS), said
    assert page.locator("#map").bounding_box()["y"] == top, "a long reason does not push the map down"
    screenshot(page, "phone-goal-given-up")
    assert sim.post("/mode", {"mode": "navigation", "map": "demo", "wait": 60}, timeout=70).status_code == 200


def test_a_goal_while_idle_is_refused_in_words_for_the_page(server, page):
    sim = server["sim"]
    assert sim.post("/mode", {"mode": "idle", "wait": 60}, timeout=70).status_code == 200
    try:
        page.wait_for_function("document.getElementById('mode').dataset.mode === 'idle'", timeout=10000)
        page.locator("#tabs button[data-tab=places]").tap()
        page.wait_for_selector("#places li button.go", timeout=10000)
        page.locator("#places li button.go").first.tap()
        page.wait_for_function("document.getElementById('error').textContent !== ''", timeout=5000)
        said = page.inner_text("#error")
        assert "Maps" in said and not any(w in said for w in API_WORDS), said
        assert "no map in use" in page.inner_text("#stale-note"), "idle is not 'localisation stalled'"
        screenshot(page, "phone-idle-refused")
    finally:
        page.locator("#tabs button[data-tab=drive]").tap()
        assert sim.post("/mode", {"mode": "navigation", "map": "demo", "wait": 60}, timeout=70).status_code == 200


def test_a_trip_a_restart_cut_short_is_told_after_it(server, page):
    sim = server["sim"]
    at_rest(sim)
    page.wait_for_function("document.getElementById('mode').dataset.state === 'running'", timeout=30000)
    assert sim.post("/goto", {"name": "kitchen"}).status_code == 202
    page.wait_for_function("document.getElementById('nav').dataset.state === 'active'", timeout=10000)
    port, folder = sim.port, sim.folder
    sim.close()  # the server stops with the robot on its way (an update, a power cut)
    page.wait_for_function("document.body.dataset.connection === 'reconnecting'", timeout=15000)
    server["sim"] = sim = PageSim(folder, port=port)
    live(page, timeout=30000)
    page.wait_for_function("document.getElementById('nav-text').textContent.includes('interrupted')",
                           timeout=15000)
    said = nav_text(page)
    assert "kitchen" in said and not any(w in said for w in API_WORDS), said
    assert sim.status()["navigation"]["state"] == "idle", "told, never resumed: the robot stays put"
    screenshot(page, "phone-trip-interrupted")
