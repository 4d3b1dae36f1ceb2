"""Explore on the phone page, in a real browser (phone, touch): the Maps panel's Explore button asks for
the map's name as Save as… does and starts an exploration; the strip under the goal line tells it in
plain words as its `explore` events come, with Stop (POST /stop), and how it ended; the spot it heads
for is ringed on the map. Refusals are in the page's words.

Two servers. The words of every state: the real app and HTTP server in this process with the fake
explorer behind it (tests/fake_explorer.py), moved on state by state by each test, so each sentence is
seen without minutes of exploring. Then the owner's story on a real ``--sim`` server and its explorer:
Explore, a name, the robot maps the demo flat by itself, Stop ends it where it is; Explore again and
the flat is saved and navigated on.
"""

import time

import pytest

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from flask_move_server.core.errors import ExploreConflict  # noqa: E402
from flask_move_server.core.events import EventBus  # noqa: E402
from flask_move_server.core.geometry import Pose2D  # noqa: E402
from flask_move_server.explore.stuck import stuck_message  # noqa: E402
from flask_move_server.waypoints.store import WaypointStore  # noqa: E402
from flask_move_server.web import create_app  # noqa: E402
from flask_move_server.web.events import StreamGate  # noqa: E402
from tests.conftest import hardened, wait_for  # noqa: E402
from tests.fake_explorer import FakeExplorer  # noqa: E402
from tests.fake_robot import FakeRobot  # noqa: E402
from tests.page_browser import DESKTOP, PageSim, RequestLog, live, screenshot  # noqa: E402
from tests.robot_fixtures import make_config  # noqa: E402

API_WORDS = ("POST ", "GET /", "PUT /", "robotctl", "curl", "Field '", "explore_conflict", "save_as")
LANDSCAPE = {"viewport": {"width": 844, "height": 390}, "has_touch": True, "is_mobile": True,
             "device_scale_factor": 1}


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    folder = tmp_path_factory.mktemp("page_explore")
    config = make_config("page_explore", folder)
    robot, bus = FakeRobot(), EventBus()
    explorer = FakeExplorer(bus, maps=["flat"], estop=robot.estop)
    explorer.attach(robot)
    app = create_app(config, robot, WaypointStore(config.waypoints.file), events=bus, explorer=explorer)
    with hardened(app, config.server, loop_timeout=60) as (_, url):
        yield type("Served", (), {"url": url, "robot": robot, "explorer": explorer, "bus": bus})
    bus.close()


@pytest.fixture(scope="module")
def page(server, browser):
    page = browser.open(server.url + "/")
    live(page)
    page.locator("#tabs button[data-tab=maps]").tap()
    yield page
    assert page.errors == []


@pytest.fixture(autouse=True)
def nothing_left_exploring(server, page):
    yield
    server.explorer.close()
    if server.explorer.cancel("test over"):
        page.wait_for_function("document.getElementById('explore').dataset.state === 'canceled'")
    server.explorer.refusal = None
    server.explorer.maps = {"flat"}  # the maps an exploration saved are forgotten
    page.answers.clear()
    if page.is_visible("#explore-close"):
        page.locator("#explore-close").tap()
    page.evaluate("document.getElementById('error').textContent = ''")


def strip(page):
    """The strip's two lines, as a person reads them."""
    return page.inner_text("#explore-title"), page.inner_text("#explore-detail")


def strip_says(page, title):
    """Wait for the strip's first line to say ``title``, whole (not cut short with "…"); both lines."""
    page.wait_for_function("document.getElementById('explore-title').textContent === {!r}".format(title))
    assert page.eval_on_selector("#explore-title", "e => e.scrollWidth <= e.clientWidth"), "cut short: " + title
    return strip(page)


def explore(page, *answers):
    page.answers.extend(answers)
    page.locator("#explore-start").tap()


def error(page):
    page.wait_for_function("document.getElementById('error').textContent !== ''")
    said = page.inner_text("#error")
    assert not any(w in said for w in API_WORDS), said
    return said


def test_explore_asks_for_the_name_then_the_strip_follows_it_to_the_saved_map(server, page):
    log = RequestLog(page)
    explore(page, "attic")
    assert page.asked[-1].startswith("Explore: the robot drives by itself to map every room it can reach")
    assert strip_says(page, "Exploring: starting to map")[1].startswith("0:0")
    sent = log.calls("POST", "/explore")
    assert len(sent) == 1 and sent[0].post_data_json["save_as"] == "attic" and "valid_until" in sent[0].post_data_json
    assert server.explorer.calls[-1][1]["save_as"] == "attic"
    assert page.is_hidden("#cancel") and page.is_hidden("#explore-start")  # the strip's Stop, one exploration
    server.explorer.advance(state="exploring", frontiers=3, known_m2=42.4, goals=5, unreachable=1, target=[1.5, 0.5],
                            elapsed=130)
    title, detail = strip_says(page, "Exploring: 3 places left to look at")
    assert detail.startswith("42 m² mapped · 1 place out of reach · 2:1"), detail
    page.wait_for_function("document.getElementById('map').dataset.exploreTarget === '1.5,0.5'")
    server.explorer.advance(state="exploring", frontiers=12, elapsed=135)
    strip_says(page, "Exploring: 12 places left to look at")  # the longest it gets, whole on a phone
    server.explorer.advance(state="exploring", frontiers=1, unreachable=0, elapsed=140)
    assert strip_says(page, "Exploring: 1 place left to look at")[1].startswith("42 m² mapped · 2:2")
    server.explorer.advance(state="returning", target=[0.0, 0.0])
    assert strip_says(page, "Coming back to where it started")[1].startswith("42 m² mapped · ")
    server.explorer.advance(state="saving", target=None)
    strip_says(page, "Saving the map as attic")
    assert page.get_attribute("#map", "data-explore-target") == ""
    server.explorer.advance(state="done", map="attic", elapsed=185)
    assert strip_says(page, "Done: saved attic") == ("Done: saved attic", "Now navigating on it · 42 m² mapped in 3:05")
    assert page.get_attribute("#explore", "data-state") == "done" and page.is_visible("#explore-close")
    assert page.is_visible("#explore-start")
    page.locator("#explore-close").tap()
    page.wait_for_selector("#explore", state="hidden")


def test_stop_on_the_strip_stops_the_robot_and_ends_it(server, page):
    explore(page, "attic")
    strip_says(page, "Exploring: starting to map")
    server.explorer.advance(state="exploring", frontiers=4, known_m2=12.0, goals=1, target=[2.0, 1.0])
    strip_says(page, "Exploring: 4 places left to look at")
    page.locator("#explore-stop").tap()
    assert strip_says(page, "Exploring stopped") == (
        "Exploring stopped", "STOP was pressed. The map so far is not saved (Maps → Save as…)")
    assert ("stop",) in server.robot.calls
    assert server.explorer.current()["state"] == "canceled"
    page.wait_for_function("document.getElementById('stop').dataset.outcome === 'stopped'")


def test_a_failure_is_told_in_red_with_the_robots_reason(server, page):
    explore(page, "attic")
    strip_says(page, "Exploring: starting to map")
    server.explorer.advance(state="failed", message="Mapping did not start: slam_gmapping died (GET /mode says why).")
    assert strip_says(page, "Exploring failed")[1] == "Mapping did not start: slam_gmapping died."
    assert page.eval_on_selector("#explore", "e => getComputedStyle(e).backgroundColor") == "rgb(255, 205, 210)"


def test_a_robot_that_could_not_move_is_told_in_red_with_where_it_stands(server, page):
    explore(page, "attic")
    strip_says(page, "Exploring: starting to map")
    message = stuck_message(Pose2D(2.4, 1.1, 0.0), 2, 5)
    server.explorer.advance(state="stuck", message=message)
    title, text = strip_says(page, "Stuck: the robot could not move")
    assert text == message and text.startswith("Stuck near x 2.4, y 1.1: drive the robot free")
    assert page.eval_on_selector("#explore", "e => getComputedStyle(e).backgroundColor") == "rgb(255, 205, 210)"
    screenshot(page, "phone-explore-stuck")
    page.set_viewport_size(DESKTOP["viewport"])  # a page opened later would not show an ending: this one, wider
    strip_says(page, "Stuck: the robot could not move")
    screenshot(page, "desktop-explore-stuck")


def test_a_saved_name_asks_before_replacing_it(server, page):
    explore(page, "flat", False)  # the name, then: replace it? no
    page.wait_for_function("() => document.querySelector('#explore').hidden")
    page.wait_for_timeout(300)
    assert page.asked[-1] == "A map called flat exists. Replace it (and its places)?"
    assert server.explorer.current() is None or server.explorer.current()["save_as"] != "flat"
    explore(page, "flat", True)
    strip_says(page, "Exploring: starting to map")
    assert server.explorer.calls[-1] == ("start", {"save_as": "flat", "then": "navigation", "max_minutes": 30.0,
                                                   "return_home": True, "overwrite": True})


def test_a_dismissed_name_starts_nothing(server, page):
    calls = len(server.explorer.calls)
    explore(page, False)
    page.wait_for_timeout(300)
    assert len(server.explorer.calls) == calls and page.is_hidden("#explore")


def test_refusals_are_said_in_the_pages_words(server, page):
    server.explorer.refusal = ExploreConflict("Run 3 (rounds) is running: cancel it first (POST /runs/3/cancel).")
    explore(page, "attic")
    assert error(page) == "A route is running: press Cancel on its strip at the top first, or wait until it ends."
    page.evaluate("document.getElementById('error').textContent = ''")
    explore(page, "a/b")
    assert "'/' is not allowed" in error(page)


def test_explore_is_greyed_while_the_e_stop_is_latched(server, page):
    server.robot.engage_estop("api")
    server.bus.publish("estop", server.robot.estop_status())  # the reporter's part, on the real server
    try:
        page.wait_for_function("document.getElementById('explore-start').disabled")
    finally:
        server.robot.release_estop()
        server.bus.publish("estop", server.robot.estop_status())
    page.wait_for_function("!document.getElementById('explore-start').disabled")


def test_a_page_opened_later_shows_the_one_under_way_but_not_an_old_ending(server, page, browser):
    explore(page, "attic")
    strip_says(page, "Exploring: starting to map")  # the page's POST reached the explorer: now it may go on
    server.explorer.advance(state="exploring", frontiers=2, known_m2=30.0, goals=3, target=[1.0, 1.0])
    strip_says(page, "Exploring: 2 places left to look at")
    opened = []
    try:
        other = browser.open(server.url + "/")
        opened.append(other)
        live(other)
        assert strip_says(other, "Exploring: 2 places left to look at")
        server.explorer.advance(state="done", map="attic")
        strip_says(other, "Done: saved attic")
        late = browser.open(server.url + "/")
        opened.append(late)
        live(late)
        late.wait_for_timeout(500)
        assert late.is_hidden("#explore"), "an exploration that ended before the page opened is not news"
        assert other.errors == [] and late.errors == []
    finally:
        for each in opened:
            each.context.close()  # its event stream ends with its connection


def test_a_page_that_polls_follows_it_too(server, browser, tmp_path):
    """No stream to spare (server.max_streams taken): the page reads /status, and /explore with the mode."""
    config = make_config("page_explore_polled", tmp_path)
    app = create_app(config, server.robot, WaypointStore(config.waypoints.file), events=server.bus,
                     explorer=server.explorer)
    app.extensions["flask_move_server"]["streams"] = StreamGate(max_streams=0)
    server.explorer.start("cellar")
    server.explorer.advance(state="exploring", frontiers=5, known_m2=20.0, goals=2, target=[1.0, 1.0])
    with hardened(app, config.server) as (_, url):
        polled = browser.open(url + "/")
        try:
            polled.wait_for_function("document.body.dataset.connection === 'polling'", timeout=20000)
            strip_says(polled, "Exploring: 5 places left to look at")
            server.explorer.advance(state="returning")
            strip_says(polled, "Coming back to where it started")
            assert polled.errors == []
        finally:
            polled.context.close()


@pytest.mark.parametrize("device", [LANDSCAPE, DESKTOP], ids=["phone on its side", "desktop"])
def test_the_strip_fits_a_phone_on_its_side_and_a_desktop(server, page, browser, device):
    server.explorer.refusal = None
    explore(page, "attic")
    strip_says(page, "Exploring: starting to map")  # the page's POST reached the explorer: now it may go on
    server.explorer.advance(state="exploring", frontiers=12, known_m2=142.0, goals=25, unreachable=3,
                            target=[1.0, 1.0], elapsed=3725)
    other = browser.open(server.url + "/", device=device)
    try:
        live(other)
        other.locator("#tabs button[data-tab=maps]").click()
        title, detail = strip_says(other, "Exploring: 12 places left to look at")
        assert detail.startswith("142 m² mapped · 3 places out of reach · 1:02:"), detail  # an hour and 2 minutes
        strip_box, stop_box = other.locator("#explore").bounding_box(), other.locator("#explore-stop").bounding_box()
        assert stop_box["x"] + stop_box["width"] <= strip_box["x"] + strip_box["width"] + 0.5
        assert other.errors == []
    finally:
        other.context.close()  # its event stream ends with its connection


# the real explorer on the simulated demo flat ----------------------------------------------------

EXPLORE_WAIT = 420  # s: the demo flat takes about two minutes at the sim's speed (tests/test_explore_sim.py)


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_explore_sim"))
    yield server
    server.close()


@pytest.fixture(scope="module")
def sim_page(sim, browser):
    page = browser.open(sim.url + "/")
    live(page)
    page.wait_for_function("document.getElementById('map').dataset.imageRect")
    page.locator("#tabs button[data-tab=maps]").tap()
    yield page
    assert page.errors == []


def exploring(sim):
    return sim.get("/explore").json()["exploration"]


def stands(sim, seconds=1.0):
    """The simulated robot comes to rest and then does not move for ``seconds``."""
    time.sleep(0.5)
    a = sim.status()["sim"]["true_pose"]
    time.sleep(seconds)
    b = sim.status()["sim"]["true_pose"]
    return abs(a["x"] - b["x"]) < 0.01 and abs(a["y"] - b["y"]) < 0.01


def test_on_the_sim_explore_maps_the_flat_and_stop_ends_it_where_it_is(sim, sim_page, browser):
    page = sim_page
    page.answers.append("halfway")
    page.locator("#explore-start").tap()
    page.wait_for_function("document.getElementById('explore').dataset.state === 'exploring'", timeout=60000)
    page.wait_for_function("document.getElementById('mode').dataset.mode === 'mapping'")
    wait_for(lambda: exploring(sim)["goals"] >= 2 and exploring(sim)["known_m2"] > 15, timeout=120,
             message="the map to grow over two frontier goals", interval=0.5)
    page.wait_for_function("document.getElementById('map').dataset.exploreTarget !== ''")
    title, detail = strip(page)
    assert title.endswith(" left to look at") or title == "Exploring: looking for places not seen yet", title
    assert " m² mapped · " in detail, detail
    screenshot(page, "phone-explore")
    for device, name in ((LANDSCAPE, "phone-explore-landscape"), (DESKTOP, "desktop-explore")):
        other = browser.open(sim.url + "/", device=device)
        live(other)
        other.wait_for_function("document.getElementById('map').dataset.imageRect")
        other.wait_for_function("document.getElementById('explore').dataset.state === 'exploring'")
        other.wait_for_timeout(1500)  # the robot drawn where it is, the plan in
        screenshot(other, name)
        assert other.errors == []
        other.context.close()

    page.locator("#explore-stop").tap()
    assert strip_says(page, "Exploring stopped")[1] == "STOP was pressed. The map so far is not saved (Maps → Save as…)"
    assert exploring(sim)["state"] == "canceled" and exploring(sim)["map"] is None
    assert stands(sim)
    assert sim.get("/mode").json()["mode"] == "mapping"  # the map made so far is there to save
    screenshot(page, "phone-explore-stopped")
    page.locator("#explore-close").tap()


@pytest.mark.timeout(EXPLORE_WAIT + 60)  # ~80 s alone; past pytest's 120 s beside a busy worker (it failed so)
def test_on_the_sim_explore_goes_on_to_the_saved_map_and_navigates_on_it(sim, sim_page):
    page = sim_page
    page.answers.append("flat")
    page.locator("#explore-start").tap()
    page.wait_for_function("document.getElementById('explore').dataset.state === 'exploring'", timeout=60000)
    page.wait_for_function("document.getElementById('explore').dataset.state === 'done'", timeout=EXPLORE_WAIT * 1000)
    title, detail = strip(page)
    assert title == "Done: saved flat" and detail.startswith("Now navigating on it · ") and " m² mapped in " in detail
    page.wait_for_function("document.getElementById('mode').textContent === 'navigating on flat'", timeout=60000)
    page.wait_for_selector('#maps li[data-name="flat"][data-active="1"]')
    assert page.get_attribute("#map", "data-explore-target") == ""
    screenshot(page, "phone-explore-done")
    page.locator("#explore-close").tap()
    page.wait_for_selector("#explore", state="hidden")
