"""The Routes panel and the run strip as an owner uses them, in a real browser (phone, touch) against a
real ``--sim`` server.

A route is made by tapping places on the map in order, saved, listed and run; the strip under the
goal line follows the run (from its `run` events), pauses and resumes it (the robot stops and goes
on) and cancels it; the map numbers the stops and ticks those done. Refusals are in the page's words.
One server and one page for the module: the tests run in order, each leaving no run under way.
"""

import json
import math
import time

import pytest

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from tests.conftest import wait_for  # noqa: E402
from tests.page_browser import DESKTOP, PageSim, live, on_the_map, screenshot  # noqa: E402

API_WORDS = ("POST ", "GET /", "PUT /", "robotctl", "curl", "Field '")
LANDSCAPE = {"viewport": {"width": 844, "height": 390}, "has_touch": True, "is_mobile": True,
             "device_scale_factor": 1}
ROUTE = ["sofa", "dock", "sofa"]  # a metre apart: a leg takes a second or two at the sim's speed


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_routes"))
    yield server
    server.close()


@pytest.fixture(scope="module")
def page(sim, browser):
    page = on_the_map(browser, sim)
    page.locator("#tabs button[data-tab=routes]").tap()
    yield page
    assert page.errors == []


@pytest.fixture(autouse=True)
def no_run_left(sim):
    yield
    sim.post("/estop/release")
    sim.post("/stop")


def shown_route(page):
    return json.loads(page.get_attribute("#map", "data-route") or "[]")


def dot(page, sim, name):
    """Where the page draws the place ``name``: page px, from its view and the robot's own numbers."""
    place = sim.get("/waypoints/" + name).json()
    scale, ox, oy = (float(v) for v in page.get_attribute("#map", "data-view").split(","))
    box = page.locator("#map").bounding_box()
    return box["x"] + ox + place["x"] * scale, box["y"] + oy - place["y"] * scale


def strip(page):
    return page.inner_text("#run").replace("\n", " ")


def error(page):
    page.wait_for_function("document.getElementById('error').textContent !== ''")
    said = page.inner_text("#error")
    assert not any(w in said for w in API_WORDS), said
    return said


def clear_error(page):
    page.evaluate("document.getElementById('error').textContent = ''")


def motors_still(sim, seconds=1.0):
    """The robot stands: the motors at zero and it did not move over ``seconds``."""
    wait_for(lambda: sim.status()["motors"]["left"] == 0.0 and sim.status()["motors"]["right"] == 0.0,
             timeout=5, message="the motors to stop")
    a = sim.pose()
    time.sleep(seconds)
    b = sim.pose()
    return math.hypot(a["x"] - b["x"], a["y"] - b["y"]) < 0.02


def make_route(page, sim, name, stops):
    page.locator("#new-route").tap()
    page.wait_for_selector("#route-editor:not([hidden])")
    for stop in stops:
        page.touchscreen.tap(*dot(page, sim, stop))
    page.fill("#route-name", name)


def test_a_route_is_made_by_tapping_places_in_order_and_saved(sim, page):
    make_route(page, sim, "rounds", ROUTE)
    assert [s["name"] for s in shown_route(page)] == ROUTE  # numbered on the map, in order
    assert page.locator("#route-stops li").all_inner_texts() == ["1 sofa ✕", "2 dock ✕", "3 sofa ✕"]
    page.fill("#route-loops", "2")
    page.select_option("#route-failure", "skip")
    page.fill("#route-schedule", "9pm")
    page.locator("#route-save").tap()
    said = error(page)  # the server's 400, in the page's words
    assert said.startswith("Runs by itself at: \"9pm\" is not a time") and "21:30" in said, said
    page.fill("#route-schedule", "21:30, mon,wed 09:00")
    clear_error(page)
    page.evaluate("document.getElementById('tab-routes').scrollTop = 0")
    screenshot(page, "phone-routes-edit")
    page.locator("#route-save").tap()
    page.wait_for_selector('#routes li[data-name="rounds"]')
    saved = sim.get("/routes/rounds").json()
    assert saved.pop("next_run")  # when the timetable runs it next, which the list says
    assert saved == {"name": "rounds", "waypoints": ROUTE, "loops": 2, "dwell": 0.0, "on_failure": "skip",
                     "schedule": ["21:30", "mon,wed 09:00"]}
    note = page.inner_text('#routes li[data-name="rounds"] .note')
    assert "sofa → dock → sofa" in note and "twice" in note and "at 21:30, mon,wed 09:00" in note and "next " in note
    assert shown_route(page) == [] and page.get_attribute("#map", "data-gesture") == "go"


def test_run_it_the_strip_follows_and_pause_stops_the_robot_until_resumed(sim, page):
    page.locator('#routes li[data-name="rounds"] button', has_text="Run").tap()
    page.wait_for_selector("#run:not([hidden])")
    assert [page.text_content(part) for part in ("#run-name", "#run-loop", "#run-where")] == [
        "rounds", "loop 1 of 2", "1 of 3: sofa"]
    assert not page.is_visible("#cancel")  # one Cancel: the strip's, for the run
    page.wait_for_function("document.getElementById('run-where').textContent === '2 of 3: dock'",
                           timeout=20000)
    assert [s["state"] for s in shown_route(page)][:2] == ["visited", "current"]  # ticked, and where it goes now
    screenshot(page, "phone-routes")
    page.locator("#run-pause").tap()
    page.wait_for_function("document.getElementById('run').dataset.state === 'paused'")
    assert "paused · " in strip(page)
    page.wait_for_function("document.getElementById('nav-text').textContent === 'paused: the round waits'")
    assert motors_still(sim)
    page.locator("#run-resume").tap()
    page.wait_for_function("document.getElementById('run').dataset.state === 'running'")
    wait_for(lambda: sim.status()["motors"]["left"] != 0.0, timeout=5, message="the robot to go on")


def test_a_run_event_moves_the_strip_on_and_cancel_ends_the_run(sim, page):
    page.locator('#routes li[data-name="rounds"] button', has_text="Run").tap()
    page.wait_for_selector("#run:not([hidden])")
    run = sim.get("/runs").json()["runs"][0]
    assert run["state"] == "running"
    before = page.inner_text("#run-where")
    assert sim.post("/runs/{}/skip".format(run["id"])).status_code == 200  # not from this page: only its event
    page.wait_for_function("(b) => document.getElementById('run-where').textContent !== b", arg=before)
    if sim.get("/runs/{}".format(run["id"])).json()["loop"] == 1:  # the stop skipped is in the loop drawn
        page.wait_for_function("JSON.parse(document.getElementById('map').dataset.route)"
                               ".some((s) => s.state === 'missed')")
    page.locator("#run-cancel").tap()
    page.wait_for_selector("#run", state="hidden")
    assert sim.get("/runs/{}".format(run["id"])).json()["state"] == "canceled"
    page.wait_for_function("document.getElementById('done').textContent === 'rounds: cancelled'")
    past = page.locator('#runs li[data-id="{}"] .note'.format(run["id"]))
    assert past.inner_text() == "cancelled"
    assert shown_route(page) == []


def test_refusals_and_stops_by_others_are_in_words(sim, page):
    r = sim.post("/runs", {"waypoints": ["sofa", "dock"], "loops": 0})
    assert r.status_code == 202, r.text
    page.wait_for_selector("#run:not([hidden])")
    assert page.inner_text("#run-name") == "a list of places" and "until stopped" in strip(page)
    page.locator('#routes li[data-name="rounds"] button', has_text="Run").tap()
    assert error(page).startswith("Another route is running: press Cancel on its strip")
    clear_error(page)
    assert sim.post("/estop").status_code == 200  # the e-stop ends the run and greys Run
    page.wait_for_selector("#run", state="hidden")
    page.wait_for_function("document.querySelector('#routes li[data-name=rounds] button').disabled")
    run_id = r.json()["run"]["id"]
    assert page.inner_text('#runs li[data-id="{}"] .note'.format(run_id)) == "stopped: the e-stop was pressed"
    sim.post("/estop/release")
    page.wait_for_function("!document.querySelector('#routes li[data-name=rounds] button').disabled")


def test_deleting_a_place_a_route_uses_says_why(sim, page):
    clear_error(page)  # the last test's run, ended by the e-stop, said so there: not this test's answer
    page.locator("#tabs button[data-tab=places]").tap()
    page.answers.append(True)  # "Delete the place sofa?"
    page.locator('#places li[data-name="sofa"] button', has_text="Delete").tap()
    assert error(page) == ("The place sofa is a stop of the route rounds: take it out (Routes → Edit) or delete "
                           "the route first.")
    assert sim.get("/waypoints/sofa").status_code == 200
    clear_error(page)
    page.locator("#tabs button[data-tab=routes]").tap()


def test_edit_and_delete_a_route(sim, page):
    page.locator('#routes li[data-name="rounds"] button', has_text="Edit").tap()
    assert page.input_value("#route-name") == "rounds" and page.input_value("#route-schedule") == "21:30, mon,wed 09:00"
    page.locator("#route-stops li").nth(2).locator("button").tap()  # the second sofa out
    page.locator('#route-picker button[data-name="office"]').tap()  # office from the list instead
    page.fill("#route-name", "evening")
    page.locator("#route-save").tap()
    page.wait_for_selector('#routes li[data-name="evening"]')
    page.wait_for_selector('#routes li[data-name="rounds"]', state="detached")
    assert sim.get("/routes/evening").json()["waypoints"] == ["sofa", "dock", "office"]
    page.answers.append(True)  # "Delete the route evening?"
    page.locator('#routes li[data-name="evening"] button', has_text="Delete").tap()
    page.wait_for_selector('#routes li[data-name="evening"]', state="detached")
    assert sim.get("/routes").json() == {"routes": []} and page.asked[-1].startswith("Delete the route evening?")


RESULTS = [  # a run as GET /runs shows it, and how the Last runs list says it ended
    ({"state": "succeeded", "missed": []}, "done"),
    ({"state": "succeeded", "missed": [{"name": "office", "loop": 1, "reason": "skipped (POST /runs/4/skip)"}]},
     "done, but skipped office"),
    ({"state": "failed", "missed": [{"name": "office", "loop": 1, "reason": "No path to the goal."}],
      "message": "Could not reach office: No path to the goal."}, "missed office: no path to the goal"),
    ({"state": "canceled", "message": "Stopped (POST /stop)."}, "stopped: STOP was pressed"),
    ({"state": "canceled", "message": "The e-stop was engaged (its button)."},
     "stopped: the e-stop button was pressed"),
    ({"state": "canceled", "message": "A goal to kitchen (POST /goto) took the robot elsewhere."},
     "stopped: the robot was sent to kitchen"),
    ({"state": "canceled", "message": "Driven by joystick (POST /teleop)."},
     "stopped: the robot was driven with the joystick"),
    ({"state": "canceled", "message": "Canceled (POST /runs/4/cancel)."}, "cancelled"),
    ({"state": "skipped", "message": "Not run at its scheduled time: The robot was on its way to kitchen.",
      "started": "2030-01-01T21:30:00"}, "skipped at 21:30: the robot was on its way to kitchen"),
    ({"state": "interrupted", "message": "The server stopped while this run was under way; resume it to go on."},
     "interrupted: the robot's server stopped under it"),
]


def test_how_runs_ended_is_said_in_words(page):
    runs = [dict({"missed": [], "message": None, "started": None}, **run) for run, _ in RESULTS]
    said = page.evaluate("(runs) => import('/static/js/runwords.js').then((w) => runs.map(w.runResult))", runs)
    # the time as this browser shows times: 21:30 in its locale's own way, and its weekday (not today)
    said[-2] = said[-2].replace(page.evaluate("() => import('/static/js/runwords.js').then((w) => "
                                              "w.clock('2030-01-01T21:30:00'))"), "21:30")
    assert said == [words for _, words in RESULTS]


@pytest.mark.parametrize("device,name", [(LANDSCAPE, "phone-routes-landscape"), (DESKTOP, "desktop-routes")])
def test_the_strip_and_the_panel_at_other_sizes(sim, browser, device, name):
    sim.post("/stop")
    body = {"waypoints": ["office", "dock"], "loops": 0, "on_failure": "skip"}  # on, whatever the sim's planner says
    assert sim.post("/runs", body).status_code == 202
    other = browser.open(sim.url + "/", device=device)
    live(other)
    tab = other.locator("#tabs button[data-tab=routes]")
    if device is LANDSCAPE:
        tab.tap()
    else:
        tab.click()  # a desktop has no touch
    other.wait_for_selector("#run:not([hidden])")
    other.wait_for_function("document.getElementById('map').dataset.imageRect")
    run = other.locator("#run").bounding_box()
    for button in ("#run-pause", "#run-skip", "#run-cancel"):
        b = other.locator(button).bounding_box()
        assert b["x"] + b["width"] <= run["x"] + run["width"] + 1 and b["y"] >= run["y"] - 1, button
    screenshot(other, name)
    assert other.errors == []
    other.close()
