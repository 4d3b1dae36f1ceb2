"""The phone page looks at the laser against the map: a real ``--sim`` server, Debian's chromium at phone
size with touch.

Set a pose well off (as by eye, a few degrees and decimetres out), the laser's dots miss the walls, and
the page says so in a yellow banner with "Set position", though AMCL's estimate is sure of itself. The
Pose gesture shows the laser where it would lie with the robot at the pose being dragged, and how much
of it lies on the walls: dragged at the truth it fits, and once let go the banner goes.
"""

import math

import pytest

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from tests.conftest import wait_for  # noqa: E402
from tests.page_browser import Finger, PageSim, on_the_map, screenshot  # noqa: E402
from tests.test_page import Screen, on_page  # noqa: E402

WARNED = "!document.getElementById('laserfit').hidden"
CLEAR = "document.getElementById('laserfit').hidden"


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_laserfit"))
    yield server
    server.close()


@pytest.fixture(scope="module")
def page(sim, browser):
    page = on_the_map(browser, sim)
    yield page
    assert page.errors == []


def truth(sim):
    return sim.status()["sim"]["true_pose"]


def test_a_right_pose_fits_and_no_banner_is_shown(sim, page):
    page.wait_for_function("Number(document.getElementById('map').dataset.laserFit) >= 0.8", timeout=15000)
    page.wait_for_timeout(2500)  # two seconds of scans
    assert page.is_hidden("#laserfit")


def test_a_pose_set_off_by_eye_is_told_though_amcl_is_sure_of_it(sim, page):
    t = truth(sim)
    r = sim.post("/pose", {"x": t["x"] + 0.4, "y": t["y"] - 0.2, "yaw": t["yaw"] + math.radians(15)})
    assert r.status_code == 200, r.text
    page.wait_for_function(WARNED, timeout=15000)
    text = page.inner_text("#laserfit-text")
    assert text.startswith("The laser does not match the map here (") and "set the robot's position" in text
    assert float(page.get_attribute("#map", "data-laser-fit")) < 0.5
    screenshot(page, "phone-laser-off")


def test_set_position_shows_the_laser_at_the_dragged_pose_and_the_truth_fits(sim, page):
    page.locator("#laserfit-set").tap()
    assert page.get_attribute("#map", "data-gesture") == "pose"
    t = truth(sim)
    screen = Screen(page, sim)
    start = on_page(page, screen.screen(t["x"], t["y"]))
    ahead = on_page(page, screen.screen(t["x"] + 0.6 * math.cos(t["yaw"]), t["y"] + 0.6 * math.sin(t["yaw"])))
    finger = Finger(page, start)
    for step in range(1, 9):
        finger.move((start[0] + (ahead[0] - start[0]) * step / 8, start[1] + (ahead[1] - start[1]) * step / 8))
    page.wait_for_timeout(200)
    fit = page.get_attribute("#map", "data-pose-fit")
    assert fit and float(fit) >= 0.8, fit  # the dots lie on the walls there
    screenshot(page, "phone-pose-laser")
    finger.lift()
    page.wait_for_function(CLEAR, timeout=15000)  # the pose set: the laser fits again
    pose = sim.pose()
    assert math.hypot(pose["x"] - t["x"], pose["y"] - t["y"]) < 0.15
    wait_for(lambda: float(page.get_attribute("#map", "data-laser-fit")) >= 0.7, timeout=10, message="a fit")
