"""The phone page tells a stuck robot: Debian's chromium at phone size (390x844, touch), driven by
Playwright, against a real ``flask-move-server --sim`` whose robot is wedged on the office door's jamb.

Pushed there with the joystick, a red banner says it is pressed against something and where, with
"Back out" (it backs out by itself) and "Joystick" (brings the joystick up); Back out turns it amber
while the robot backs out slowly, and it goes once the robot is free; sent on to the office from the
Places list, it arrives. Screenshots at phone size, on its side and on a desktop (build/screenshots,
docs/images).
"""

import pytest

pytest.importorskip("playwright")

from tests.conftest import wait_for  # noqa: E402
from tests.page_browser import DESKTOP, PageSim, live, on_the_map, screenshot  # noqa: E402

LANDSCAPE = {"viewport": {"width": 844, "height": 390}, "has_touch": True, "is_mobile": True,
             "device_scale_factor": 1}


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_stuck"))
    yield server
    server.close()


@pytest.fixture(scope="module")
def page(sim, browser):
    page = on_the_map(browser, sim)
    yield page
    assert page.errors == []


def banner(page):
    return page.evaluate("""() => { const b = document.getElementById('stuck');
        return {hidden: b.hidden, state: b.dataset.state, text: document.getElementById('stuck-text').textContent,
                back: !document.getElementById('stuck-back').hidden,
                joystick: !document.getElementById('stuck-drive').hidden}; }""")


def lines_shown(page):
    """How many lines of the banner's words a person sees (two at most on a phone, until tapped)."""
    return page.eval_on_selector("#stuck-text",
                                 "e => Math.round(e.clientHeight / parseFloat(getComputedStyle(e).lineHeight))")


def test_pressed_on_the_jamb_the_banner_says_where_in_red_and_brings_up_the_joystick(sim, page, browser):
    r = sim.post("/goto", {"x": 0.2, "y": 1.9, "yaw": 1.57, "wait": 60}, timeout=70)
    assert r.status_code == 200, r.text
    page.locator("#tabs button[data-tab=places]").tap()  # the owner looks at the places meanwhile
    for _ in range(150):
        if sim.status()["stuck"]["state"] == "stuck":
            break
        sim.post("/teleop", {"linear": 0.2, "angular": 0.0})
        page.wait_for_timeout(100)
    page.wait_for_function("!document.getElementById('stuck').hidden")
    shown = banner(page)
    assert shown["state"] == "stuck" and shown["back"] and shown["joystick"], shown
    assert shown["text"].startswith("Pressed against something near sofa: let it back out by itself, or drive it "
                                    "back with the joystick")
    assert page.eval_on_selector("#stuck", "e => getComputedStyle(e).backgroundColor") == "rgb(176, 0, 32)"
    assert lines_shown(page) <= 2
    screenshot(page, "phone-stuck")
    for device, name in ((LANDSCAPE, "landscape-stuck"), (DESKTOP, "desktop-stuck")):
        other = browser.open(sim.url + "/", device=device)
        live(other)
        other.wait_for_function("!document.getElementById('stuck').hidden")  # a page opened later sees it too
        other.wait_for_function("document.getElementById('map').dataset.imageRect")  # its map drawn
        screenshot(other, name)
        other.close()
    page.locator("#stuck-drive").tap()
    assert page.get_attribute("#tabs button[data-tab=drive]", "aria-selected") == "true"
    assert page.is_visible("#pad")


def test_back_out_turns_it_amber_while_it_backs_out_then_it_goes_and_the_robot_is_sent_on(sim, page):
    before = sim.status()["sim"]["true_pose"]
    page.locator("#stuck-back").tap()
    page.wait_for_function("document.getElementById('stuck').dataset.state === 'backing_out'")
    shown = banner(page)
    assert shown["text"] == "Stuck near sofa: backing out 30 cm slowly." and not shown["back"], shown
    assert page.eval_on_selector("#stuck", "e => getComputedStyle(e).backgroundColor") == "rgb(255, 179, 0)"
    assert page.inner_text("#nav-text") != "driving with the joystick"  # the robot drives itself
    screenshot(page, "phone-stuck-backing-out")
    page.wait_for_function("document.getElementById('stuck').hidden", timeout=30000)
    assert before["y"] - sim.status()["sim"]["true_pose"]["y"] > 0.1  # it came back off the wall
    page.locator("#tabs button[data-tab=places]").tap()
    page.locator("#places li[data-name=office] button.go").tap()
    wait_for(lambda: sim.status()["navigation"]["state"] == "succeeded", timeout=90, message="the office")
    page.wait_for_function("document.getElementById('nav-text').textContent === 'arrived at office'")
    assert page.is_hidden("#stuck")
