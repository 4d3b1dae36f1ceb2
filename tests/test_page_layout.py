"""The page's feedback and layout (issue 22, item 7), in Debian's chromium against a real ``--sim`` server.

What an owner notices: a word when Mark, Pose, Rename and Delete worked; a question before marking
a place inside a wall; place names on the map that do not pile on each other or on the robot, long
ones shortened, each place's heading drawn; an error line that does not push the map away from a
finger aiming at it; a Places list in name order with a box to find one, and a rename that keeps
the place; the map clear of the gesture buttons on a phone on its side; the keys named on a desktop.
"""

import itertools
import math

import pytest
import requests

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from tests.conftest import wait_for  # noqa: E402
from tests.page_browser import (  # noqa: E402
    DESKTOP,
    PHONE,
    Finger,
    PageSim,
    RequestLog,
    canvas_box,
    live,
    robot_px,
    screenshot,
)
from tests.test_page import Screen, on_page  # noqa: E402

LANDSCAPE = dict(PHONE, viewport={"width": 844, "height": 390})
TICK_RGB = (0x00, 0x69, 0x5c)  # a waypoint's dot and heading tick


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_layout"))
    yield server
    server.close()


def open_page(sim, browser, device=PHONE):
    page = browser.open(sim.url + "/", device=device)
    live(page)
    page.wait_for_function("document.getElementById('map').dataset.imageRect")
    page.wait_for_function("document.getElementById('map').dataset.robotPx")
    return page


@pytest.fixture
def page(sim, browser):
    page = open_page(sim, browser)
    yield page
    assert page.errors == []
    page.close()


def place_path(sim, name):
    return sim.url + "/waypoints/" + requests.utils.quote(name)


def place_names(sim):
    return [w["name"] for w in sim.get("/waypoints").json()["waypoints"]]


@pytest.fixture
def places(sim):
    """Adds waypoints through the API; afterwards only the demo's are left, whatever the test added."""
    original = set(place_names(sim))

    def add(name, x, y, yaw=0.0):
        r = requests.put(place_path(sim, name), json={"x": x, "y": y, "yaw": yaw}, headers=sim.headers(), timeout=10)
        assert r.status_code in (200, 201), r.text
    yield add
    for name in set(place_names(sim)) - original:
        requests.delete(place_path(sim, name), headers=sim.headers(), timeout=10)


def places_tab(page):
    page.locator("#tabs button[data-tab=places]").tap()


def done_says(page, text):
    page.wait_for_function("(t) => document.getElementById('done').textContent === t", arg=text, timeout=5000)


def an_error_shows(page):
    """Rename onto a name no place can have: the robot's 400 appears on the error line."""
    page.answers.append("no/slash")
    page.locator('#places li[data-name="kitchen"] button', has_text="Rename").tap()
    page.wait_for_function("document.getElementById('error').textContent.includes('name')", timeout=5000)


def drag_on_map(page, start, offset=(40, 0)):
    finger = Finger(page, on_page(page, start))
    finger.move(on_page(page, (start[0] + offset[0], start[1] + offset[1])))
    finger.lift()


def box_of(page, selector):
    return page.locator(selector).bounding_box()


def overlap(a, b):
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def labels(page):
    return page.evaluate("JSON.parse(document.getElementById('map').dataset.labels || '[]')")


# ---- feedback ------------------------------------------------------------------------------------------

def test_mark_pose_rename_and_delete_each_say_they_worked_and_clear_an_old_error(sim, page, places):
    places_tab(page)
    an_error_shows(page)
    page.fill("#newname", "by the door")
    page.locator("#mark-form button").tap()
    done_says(page, "Saved by the door")
    assert page.inner_text("#error") == "", "a success clears the error line an earlier command left"

    log = RequestLog(page)
    page.answers.append("front door")
    page.locator('#places li[data-name="by the door"] button', has_text="Rename").tap()
    done_says(page, "Renamed by the door to front door")
    assert [r.method for r in log.requests if "/waypoints/" in r.url] == ["PATCH"], "one request: never twice"
    assert "front door" in place_names(sim) and "by the door" not in place_names(sim)

    page.answers.append(True)
    page.locator('#places li[data-name="front door"] button', has_text="Delete").tap()
    done_says(page, "Deleted front door")

    page.locator("#gesture button[data-gesture=pose]").tap()
    pose = sim.pose()
    drag_on_map(page, Screen(page, sim).screen(pose["x"], pose["y"]))  # where the robot stands
    done_says(page, "Pose set")


def test_marking_inside_a_wall_or_off_the_map_asks_first(sim, page, places):
    page.locator("#gesture button[data-gesture=mark]").tap()
    wall = page.evaluate("""() => {  // the middle of a block of black map pixels: a wall as drawn
      const c = document.getElementById('map'), d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
      const dark = (x, y) => { const i = (y * c.width + x) * 4; return d[i] < 20 && d[i + 1] < 20 && d[i + 2] < 20; };
      for (let y = 6; y < c.height - 6; y += 2) for (let x = 6; x < c.width - 6; x += 2) {
        let all = true;
        for (let dy = -5; dy <= 5 && all; dy++) for (let dx = -5; dx <= 5 && all; dx++) all = dark(x + dx, y + dy);
        if (all) return [x, y];
      }
      return null;
    }""")
    assert wall, "the demo map has thick walls"
    log = RequestLog(page)
    page.answers.append(False)  # "inside a wall. Mark it anyway?" no
    drag_on_map(page, wall)
    wait_for(lambda: page.wait_for_timeout(20) or page.asked, timeout=5, message="the question")
    assert page.asked == ["This spot is inside a wall. Mark it anyway?"]

    rect = [float(v) for v in page.get_attribute("#map", "data-image-rect").split(",")]
    off_map = (rect[0] + rect[2] / 2, rect[1] - 15) if rect[1] > 30 else (rect[0] - 15, rect[1] + rect[3] / 2)
    page.answers.extend([True, "beyond"])  # "not mapped yet. Mark it anyway?" yes, then its name
    page.locator("#gesture button[data-gesture=mark]").tap()
    drag_on_map(page, off_map)
    done_says(page, "Saved beyond")
    assert page.asked[1:] == ["This spot is not mapped yet. Mark it anyway?", "Name this place:"]

    page.answers.append("hall floor")  # free floor: no question, only the name
    page.locator("#gesture button[data-gesture=mark]").tap()
    drag_on_map(page, Screen(page, sim).screen(2.0, 0.5))
    done_says(page, "Saved hall floor")
    assert page.asked[3:] == ["Name this place:"]
    saved = [r.url.rsplit("/", 1)[1] for r in log.requests if r.method == "PUT"]
    assert saved == ["beyond", "hall%20floor"], "the refused spot in the wall was never saved"


# ---- the map's drawing ---------------------------------------------------------------------------------

def test_place_names_keep_clear_of_each_other_and_the_robot_and_long_ones_are_shortened(sim, page, places):
    long_name = "the armchair by the window where the cat sleeps"
    x, y = sim.pose()["x"], sim.pose()["y"]
    cluster = ["tv", "lamp", "rug", "shelf"]
    for i, name in enumerate(cluster):  # around the robot, 15 cm apart
        places(name, x + 0.15 * math.cos(i * 1.6), y + 0.15 * math.sin(i * 1.6))
    places(long_name, 2.0, 0.5)
    page.wait_for_function("(n) => document.getElementById('map').dataset.labels.includes(n)",
                           arg=long_name[:10], timeout=10000)
    page.wait_for_timeout(300)  # the drawn robot has eased onto its pose
    drawn = labels(page)
    assert {d["name"] for d in drawn} & set(cluster), "names in a cluster find room where they can"
    for a, b in itertools.combinations(drawn, 2):
        assert not overlap(a["box"], b["box"]), (a, b)
    rx, ry = robot_px(page)
    for d in drawn:
        assert not overlap(d["box"], [rx - 20, ry - 20, rx + 20, ry + 20]), ("on the robot", d)
    text = [d["text"] for d in drawn if d["name"] == long_name][0]
    assert text.endswith("…") and long_name.startswith(text[:-1].rstrip()) and len(text) < 25, text
    places_tab(page)
    assert page.inner_text('#places li[data-name="{}"] button.go'.format(long_name)) == long_name
    screenshot(page, "layout-labels")


def tick_colour_near(page, point):
    """Whether a pixel of the tick's colour is within 1 px of ``point`` on the canvas."""
    return page.evaluate("""([x, y, rgb]) => {
      const canvas = document.getElementById('map');
      const d = canvas.getContext('2d').getImageData(Math.round(x) - 1, Math.round(y) - 1, 3, 3).data;
      const near = (i) => [0, 1, 2].every((k) => Math.abs(d[i + k] - rgb[k]) < 30);
      for (let i = 0; i < d.length; i += 4) if (near(i)) return true;
      return false;
    }""", [point[0], point[1], list(TICK_RGB)])


@pytest.mark.parametrize("yaw", [0.0, math.pi / 2, -2.5])
def test_each_place_shows_the_way_it_faces(sim, page, places, yaw):
    places("facing", 2.0, 0.5, yaw)
    page.wait_for_function("document.getElementById('map').dataset.labels.includes('facing')", timeout=10000)
    sx, sy = Screen(page, sim).screen(2.0, 0.5)
    dirs = {"tick": yaw, "left": yaw + math.pi / 2, "back": yaw + math.pi, "right": yaw - math.pi / 2}
    seen = {k: tick_colour_near(page, (sx + 13 * math.cos(a), sy - 13 * math.sin(a))) for k, a in dirs.items()}
    assert seen == {"tick": True, "left": False, "back": False, "right": False}, seen


# ---- layout --------------------------------------------------------------------------------------------

def test_an_error_lies_over_the_map_and_never_moves_it(sim, page):
    places_tab(page)
    before = canvas_box(page)
    an_error_shows(page)
    after, error = canvas_box(page), box_of(page, "#error")
    assert after == before, "the map moved under the finger"
    assert error["y"] >= after["y"] and error["y"] + error["height"] <= after["y"] + after["height"]
    top, stop = box_of(page, "#top"), box_of(page, "#stop")
    assert error["y"] >= top["y"] + top["height"] and error["y"] + error["height"] <= stop["y"]
    for control in ("#fit", "#follow"):
        c = box_of(page, control)
        assert error["x"] + error["width"] <= c["x"], control + " covered"
    screenshot(page, "layout-error")
    page.locator("#error").tap()  # read: a tap puts it away
    page.wait_for_function("document.getElementById('error').textContent === ''", timeout=2000)


def test_the_places_list_is_in_name_order_findable_and_uses_its_height(sim, page, places):
    places_tab(page)
    page.wait_for_selector('#places li[data-name="kitchen"]', state="attached")
    assert not page.is_visible("#place-filter"), "five places need no search box"
    for i, name in enumerate(["Zebra crossing", "apple tree", "room 10", "room 9", "Bench", "attic"]):
        places(name, 1.0 + 0.3 * i, 0.5)
    page.wait_for_selector("#place-filter", state="visible")
    page.wait_for_selector('#places li[data-name="attic"]', state="attached")
    shown = page.eval_on_selector_all("#places li", "rows => rows.map(r => r.dataset.name)")
    assert shown == ["apple tree", "attic", "bedroom", "Bench", "dock", "kitchen", "office", "room 9", "room 10",
                     "sofa", "Zebra crossing"]
    visible = page.evaluate("""() => {  // whole rows on screen in the open panel, without scrolling
      const tab = document.getElementById('tab-places').getBoundingClientRect();
      return [...document.querySelectorAll('#places li')].filter(li => {
        const r = li.getBoundingClientRect(); return r.top >= tab.top && r.bottom <= tab.bottom; }).length;
    }""")
    assert visible >= 5, visible
    screenshot(page, "layout-places")
    page.locator("#place-filter").fill("ROOM")  # any case, anywhere in the name
    page.wait_for_function("document.querySelectorAll('#places li:not([hidden])').length === 3")
    shown = page.eval_on_selector_all("#places li:not([hidden])", "rows => rows.map(r => r.dataset.name)")
    assert shown == ["bedroom", "room 9", "room 10"]
    page.locator("#place-filter").fill("")
    page.wait_for_function("document.querySelectorAll('#places li:not([hidden])').length === 11")


def image_clear_of_gestures(page):
    rect = [float(v) for v in page.get_attribute("#map", "data-image-rect").split(",")]
    board, bar = canvas_box(page), box_of(page, "#gesture")
    image = [board["x"] + rect[0], board["y"] + rect[1], board["x"] + rect[0] + rect[2], board["y"] + rect[1] + rect[3]]
    return not overlap(image, [bar["x"], bar["y"], bar["x"] + bar["width"], bar["y"] + bar["height"]]), image, bar


@pytest.mark.parametrize("device, name", [(LANDSCAPE, "layout-landscape"), (DESKTOP, "layout-desktop")])
def test_the_fitted_map_is_clear_of_the_gesture_buttons(sim, browser, device, name):
    page = open_page(sim, browser, device)
    clear, image, bar = image_clear_of_gestures(page)
    assert clear, (image, bar)
    board = canvas_box(page)
    assert image[2] - image[0] >= 0.45 * board["width"] or image[3] - image[1] >= 0.6 * board["height"], \
        "the map still uses the room it has"
    screenshot(page, name)
    assert page.errors == []
    page.close()


def test_a_desktop_says_which_keys_drive_and_a_phone_does_not(sim, browser, page):
    assert not page.is_visible("#keys-hint")
    desk = open_page(sim, browser, DESKTOP)
    assert desk.is_visible("#keys-hint")
    assert "W A S D" in desk.inner_text("#keys-hint") and "arrow keys" in desk.inner_text("#keys-hint")
    hint, pad = box_of(desk, "#keys-hint"), box_of(desk, "#tab-drive")
    assert pad["y"] <= hint["y"] and hint["y"] + hint["height"] <= pad["y"] + pad["height"], "in the Drive tab"
    desk.close()
