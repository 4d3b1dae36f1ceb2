"""The phone page in a real browser (Debian's chromium, Playwright) against a real ``--sim`` server.

A phone-sized page (390×844, touch) drives the simulated robot through the same controls a person
uses: the joystick, STOP, the waypoint list, the map's markers, press-and-drag on the map, marking
places, the e-stop. What the test checks is what a person would notice: the robot moves, arrives,
stops; the waypoints file changes; the page shows it. State the page draws is read from its data-*
attributes (where the robot is drawn, where the map image is), never from test-only endpoints.
"""

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
    angle_error,
    canvas_box,
    centre,
    live,
    robot_px,
    screenshot,
)

CELLS = 2  # a goal from the map may be this many map cells from the point under the finger


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_sim"))
    yield server
    server.close()


@pytest.fixture
def page(sim, browser):
    page = browser.open(sim.url + "/")
    live(page)
    page.wait_for_function("document.getElementById('map').dataset.robotPx")
    page.wait_for_function("document.getElementById('map').dataset.imageRect")  # the sim's map: the view fitted to it
    yield page
    assert page.errors == []
    page.close()


def at_rest(sim):
    """Stop whatever the robot does and wait until it stands still."""
    sim.post("/stop")
    wait_for(lambda: sim.status()["motors"]["left"] == 0.0 and sim.status()["motors"]["right"] == 0.0, timeout=10,
             message="the motors to stop")


# ---- where things are on the screen, computed from the server's own numbers ----------------------------

def map_meta(sim):
    r = sim.get("/map")
    return r.json() if r.status_code == 200 else None


class Screen:
    """Canvas CSS px <-> metres, from the drawn image's rectangle and the server's ``/map``.

    This does not trust the page's own transform: the image rectangle the page drew and the server's
    metadata (origin, resolution, size; row 0 = the top) are enough.
    """

    def __init__(self, page, sim):
        meta, rect = map_meta(sim), page.get_attribute("#map", "data-image-rect")
        assert meta and rect, "the sim serves a map and the page draws it"
        self.left, self.top, width, height = (float(v) for v in rect.split(","))
        self.cell = meta["resolution"]
        self.ox, self.oy = meta["origin"][:2]
        self.rows = meta["height"]
        self.px_x, self.px_y = width / meta["width"], height / meta["height"]  # CSS px per cell
        self.tolerance = CELLS * self.cell  # metres

    def world(self, px, py):
        return (self.ox + (px - self.left) / self.px_x * self.cell,
                self.oy + (self.rows - (py - self.top) / self.px_y) * self.cell)

    def screen(self, x, y):
        return (self.left + (x - self.ox) / self.cell * self.px_x,
                self.top + (self.rows - (y - self.oy) / self.cell) * self.px_y)


def on_page(page, point):
    box = canvas_box(page)
    return box["x"] + point[0], box["y"] + point[1]


# ---- the tests ---------------------------------------------------------------------------------------

def test_the_robot_is_drawn_where_status_says(sim, page):
    at_rest(sim)
    page.wait_for_timeout(500)  # the drawn arrow eases to the newest pose
    pose = sim.pose()
    expected = Screen(page, sim).screen(pose["x"], pose["y"])
    drawn = robot_px(page)
    assert math.hypot(drawn[0] - expected[0], drawn[1] - expected[1]) <= 3, (drawn, expected)
    assert page.get_attribute("#map", "data-robot-stale") == "0"
    screenshot(page, "phone-map")


def test_the_joystick_drives_and_letting_go_stops(sim, page):
    at_rest(sim)
    log = RequestLog(page)
    x, y = centre(page, "#pad")
    finger = Finger(page, (x, y))
    finger.move((x, y - 60))  # forward
    wait_for(lambda: sim.status()["motors"]["left"] > 0 and sim.status()["motors"]["right"] > 0, timeout=10,
             message="the joystick to drive the motors forward")
    page.wait_for_timeout(600)  # longer than the deadman: only repeats keep it going
    wait_for(lambda: sim.status()["motors"]["left"] > 0, timeout=5,  # a loaded machine may miss one beat
             message="the joystick to repeat its command while held")
    assert len(log.calls("POST", "/teleop")) >= 3
    finger.lift()
    wait_for(lambda: log.calls("POST", "/stop"), timeout=5, message="a stop sent on release")
    wait_for(lambda: (sim.status()["motors"]["left"], sim.status()["motors"]["right"]) == (0.0, 0.0), timeout=5,
             message="the motors stopped")


HIDE_PAGE = ("Object.defineProperty(document, 'hidden', {value: true, configurable: true});"
             "document.dispatchEvent(new Event('visibilitychange'))")  # the phone locked, another app on top


@pytest.mark.parametrize("event", ["window.dispatchEvent(new Event('blur'))", HIDE_PAGE, "touchcancel"],
                         ids=["blur", "hidden", "pointercancel"])
def test_losing_focus_or_hiding_the_page_stops_the_joystick(sim, page, event):
    at_rest(sim)
    log = RequestLog(page)
    x, y = centre(page, "#pad")
    finger = Finger(page, (x, y))
    finger.move((x + 50, y))  # turn right
    wait_for(lambda: sim.status()["motors"]["left"] > 0 > sim.status()["motors"]["right"], timeout=10,
             message="the joystick to turn the robot")
    if event == "touchcancel":  # the browser takes the touch over (a system gesture): pointercancel
        finger.session.send("Input.dispatchTouchEvent", {"type": "touchCancel", "touchPoints": []})
    else:
        page.evaluate(event)
    wait_for(lambda: log.calls("POST", "/stop"), timeout=5, message="a stop sent at once")
    teleops = len(log.calls("POST", "/teleop"))
    page.wait_for_timeout(500)
    assert len(log.calls("POST", "/teleop")) == teleops, "no command after that, the finger still down"
    wait_for(lambda: sim.status()["motors"]["left"] == 0.0, timeout=5, message="the motors stopped")
    if event != "touchcancel":
        finger.lift()


def test_pinch_zooms_and_follow_keeps_the_robot_in_the_middle(sim, page):
    at_rest(sim)
    scale = float(page.get_attribute("#map", "data-view").split(",")[0])
    box = canvas_box(page)
    cx, cy = box["x"] + box["width"] / 2, box["y"] + box["height"] / 2
    session = page.context.new_cdp_session(page)

    def fingers(kind, spread):
        points = [{"x": cx - spread, "y": cy, "id": 1}, {"x": cx + spread, "y": cy, "id": 2}]
        session.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": points})
    fingers("touchStart", 30)
    for spread in (45, 60, 75, 90):
        fingers("touchMove", spread)
    session.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})
    zoomed = float(page.get_attribute("#map", "data-view").split(",")[0])
    assert zoomed > scale * 2, (scale, zoomed)
    assert sim.status()["navigation"]["state"] != "active", "a pinch is not a goal"

    page.locator("#follow").tap()
    sim.post("/goto", {"name": "kitchen"})
    page.wait_for_function("document.getElementById('nav').dataset.state === 'active'", timeout=10000)
    page.wait_for_timeout(1500)
    x, y, width, height = page.evaluate("""() => {  // one moment: the status line's wrapping resizes the map
      const c = document.getElementById('map'), r = c.getBoundingClientRect();
      return c.dataset.robotPx.split(',').map(Number).concat([r.width, r.height]);
    }""")
    assert abs(x - width / 2) < 3 and abs(y - height / 2) < 3, (x, y, width, height)
    assert page.get_attribute("#follow", "aria-pressed") == "true"
    sim.post("/stop")
    page.locator("#fit").tap()


def test_a_waypoint_added_elsewhere_appears_without_a_reload(sim, page):
    r = sim.get("/waypoints")
    assert r.status_code == 200
    put = __import__("requests").put(sim.url + "/waypoints/from a script", json={"x": 1.5, "y": 0.5, "yaw": 0.0},
                                     timeout=10)
    assert put.status_code == 201, put.text
    page.wait_for_selector('#places li[data-name="from a script"]', state="attached", timeout=10000)
    __import__("requests").delete(sim.url + "/waypoints/from a script", timeout=10)
    page.wait_for_selector('#places li[data-name="from a script"]', state="detached", timeout=10000)


def test_tapping_a_waypoint_in_the_list_sends_the_robot_there(sim, page):
    at_rest(sim)
    page.locator("#tabs button[data-tab=places]").tap()
    page.locator("#places li[data-name=sofa] button.go").tap()
    wait_for(lambda: sim.status()["navigation"]["target"] == "sofa", timeout=10, message="a goal for the sofa")
    page.wait_for_function("document.getElementById('nav').dataset.state === 'succeeded'", timeout=60000)
    assert "arrived at sofa" in page.inner_text("#nav-text")
    x, y, _ = sim.waypoint("sofa")
    pose = sim.pose()
    assert math.hypot(pose["x"] - x, pose["y"] - y) < 0.15


def test_tapping_a_waypoint_marker_on_the_map_sends_the_robot_there(sim, page):
    at_rest(sim)
    x, y, _ = sim.waypoint("dock")
    page.touchscreen.tap(*on_page(page, Screen(page, sim).screen(x, y)))
    wait_for(lambda: sim.status()["navigation"]["target"] == "dock", timeout=10, message="a goal for the dock")
    wait_for(lambda: sim.status()["navigation"]["state"] == "succeeded", timeout=60, message="arrival at the dock")


def test_a_tap_on_the_floor_does_not_move_the_robot(sim, page):
    at_rest(sim)
    log = RequestLog(page)
    screen = Screen(page, sim)
    page.touchscreen.tap(*on_page(page, screen.screen(2.0, 0.5)))  # no waypoint there
    page.wait_for_function("document.getElementById('hint').textContent.startsWith('Press and drag')")
    assert log.calls("POST", "/goto") == []


def test_press_and_drag_sends_a_goal_with_its_heading(sim, page):
    at_rest(sim)
    screen = Screen(page, sim)
    start = screen.screen(1.0, 1.0)  # free floor in the demo flat's hall
    finger = Finger(page, on_page(page, start))
    for step in range(1, 7):  # drag up and to the left: a heading of 135°
        finger.move(on_page(page, (start[0] - 8 * step, start[1] - 8 * step)))
    finger.lift()
    wait_for(lambda: sim.status()["navigation"]["goal"] is not None and sim.status()["navigation"]["target"] is None,
             timeout=10, message="a goal from the drag")
    goal = sim.status()["navigation"]["goal"]
    wx, wy = screen.world(*start)
    assert math.hypot(goal["x"] - wx, goal["y"] - wy) <= screen.tolerance, (goal, wx, wy)
    assert angle_error(goal["yaw"], 3 * math.pi / 4) < 0.1, goal
    wait_for(lambda: sim.status()["navigation"]["state"] == "succeeded", timeout=60, message="the robot to arrive")
    pose = sim.pose()
    assert math.hypot(pose["x"] - goal["x"], pose["y"] - goal["y"]) < 0.15


@pytest.mark.parametrize("button", ["#stop", "#cancel"])
def test_stop_and_cancel_end_the_goal(sim, page, button):
    at_rest(sim)
    page.locator("#tabs button[data-tab=places]").tap()
    page.locator("#places li[data-name=kitchen] button.go").tap()
    page.wait_for_function("document.getElementById('nav').dataset.state === 'active'", timeout=10000)
    assert page.inner_text("#nav-text") == "going to kitchen"
    page.locator(button).tap()
    wait_for(lambda: sim.status()["navigation"]["state"] == "canceled", timeout=10, message="the goal canceled")
    page.wait_for_function("document.getElementById('nav').dataset.state === 'canceled'", timeout=5000)


def test_a_long_place_name_is_cut_on_a_phone_but_never_the_distance_left(sim, page):
    at_rest(sim)
    name = "the far end of the kitchen by the window"
    x, y, yaw = sim.waypoint("kitchen")
    assert requests.put(sim.url + "/waypoints/" + name, json={"x": x, "y": y, "yaw": yaw},
                        headers=sim.headers(), timeout=10).status_code == 201
    try:
        page.locator("#tabs button[data-tab=places]").tap()
        page.locator('#places li[data-name="{}"] button.go'.format(name)).tap()
        page.wait_for_function("/^\\d+\\.\\d m$/.test(document.getElementById('nav-distance').textContent)",
                               timeout=10000)
        line = page.evaluate("""() => {
            const box = (id) => document.getElementById(id).getBoundingClientRect();
            const text = document.getElementById('nav-text');
            return {text: box('nav-text'), distance: box('nav-distance'), cancel: box('cancel'),
                    width: window.innerWidth, cut: text.scrollWidth > text.clientWidth};
        }""")
        assert line["cut"], "the name fits: the test no longer shows what it is about"
        assert line["text"]["right"] <= line["distance"]["left"], line
        assert line["distance"]["right"] <= line["cancel"]["left"] <= line["cancel"]["right"] <= line["width"], line
    finally:
        at_rest(sim)
        requests.delete(sim.url + "/waypoints/" + name, headers=sim.headers(), timeout=10)


def test_a_waypoints_reload_that_changes_nothing_leaves_the_rows_a_finger_may_be_on(sim, page):
    page.locator("#tabs button[data-tab=places]").tap()
    page.evaluate("() => { window.kitchenRow = document.querySelector('#places li[data-name=kitchen]'); }")
    log = RequestLog(page)
    x, y, yaw = sim.waypoint("kitchen")
    assert requests.put(sim.url + "/waypoints/kitchen", json={"x": x, "y": y, "yaw": yaw},
                        headers=sim.headers(), timeout=10).status_code == 200  # the same place: an event, no change
    wait_for(lambda: log.calls("GET", "/waypoints"), message="the page to reload the waypoints on the event")
    log.calls("GET", "/waypoints")[-1].response()  # the answer came
    page.wait_for_timeout(100)  # and the page has drawn it, or not
    assert page.evaluate("() => window.kitchenRow.isConnected"), "the rows were rebuilt though nothing changed"


def test_marking_places_renaming_and_deleting_them(sim, page, browser):
    at_rest(sim)
    page.locator("#tabs button[data-tab=places]").tap()
    page.fill("#newname", "here now")
    page.locator("#mark-form button").tap()
    page.wait_for_selector('#places li[data-name="here now"]')
    pose, saved = sim.pose(), sim.waypoint("here now")
    assert math.hypot(saved[0] - pose["x"], saved[1] - pose["y"]) < 0.05

    page.answers.append("hall spot")  # the name asked for after a press-and-drag in Mark mode
    page.locator("#gesture button[data-gesture=mark]").tap()
    screen = Screen(page, sim)
    start = screen.screen(2.0, 0.5)
    finger = Finger(page, on_page(page, start))
    finger.move(on_page(page, (start[0] + 40, start[1])))  # facing +x
    finger.lift()
    page.wait_for_selector('#places li[data-name="hall spot"]')
    x, y, yaw = sim.waypoint("hall spot")
    wx, wy = screen.world(*start)
    assert math.hypot(x - wx, y - wy) <= screen.tolerance and angle_error(yaw, 0.0) < 0.1
    assert sim.status()["navigation"]["target"] != "hall spot", "marking must not send the robot"

    page.answers.append("window")
    page.locator('#places li[data-name="here now"] button', has_text="Rename").tap()
    page.wait_for_selector('#places li[data-name="window"]')
    assert sim.waypoint("window") == saved
    page.wait_for_selector('#places li[data-name="here now"]', state="detached")

    page.answers.extend(["hall spot", False])  # renaming onto another waypoint's name: "Replace?" no
    page.locator('#places li[data-name="window"] button', has_text="Rename").tap()
    wait_for(lambda: page.wait_for_timeout(20) or "Replace the place hall spot?" in page.asked, timeout=5,
             message="the replace confirmation")
    assert sim.waypoint("hall spot") == [x, y, yaw] and sim.get("/waypoints/window").status_code == 200

    page.answers.append(False)  # "Delete the place?" answered no: nothing happens
    asked = len(page.asked)
    page.locator('#places li[data-name="window"] button', has_text="Delete").tap()
    wait_for(lambda: page.wait_for_timeout(20) or len(page.asked) > asked, message="the delete confirmation")
    assert "Delete the place window?" in page.asked[-1]
    assert sim.get("/waypoints/window").status_code == 200
    page.answers.append(True)
    page.locator('#places li[data-name="window"] button', has_text="Delete").tap()
    page.wait_for_selector('#places li[data-name="window"]', state="detached")
    assert sim.get("/waypoints/window").status_code == 404


def test_the_e_stop_latches_shows_and_is_released(sim, page):
    """While latched, what would move the robot is greyed, and a goal tried anyway is refused in
    words for a person holding a phone ("press Release"), not the API's ("POST /estop/release")."""
    at_rest(sim)
    page.locator("#estop").tap()
    page.wait_for_selector("#estop-banner", state="visible")
    assert sim.status()["estop"]["latched"] is True
    assert sim.post("/teleop", {"linear": 0.1, "angular": 0}).status_code == 409
    page.wait_for_function("document.getElementById('pad').getAttribute('aria-disabled') === 'true'", timeout=5000)
    page.locator("#tabs button[data-tab=places]").tap()
    assert page.locator("#places li[data-name=kitchen] button.go").is_disabled()
    page.locator("#tabs button[data-tab=drive]").tap()
    screen = Screen(page, sim)
    start = screen.screen(1.0, 1.0)
    finger = Finger(page, on_page(page, start))
    finger.move(on_page(page, (start[0] + 40, start[1])))
    finger.lift()
    page.wait_for_function("document.getElementById('error').textContent.includes('Release')", timeout=5000)
    said = page.inner_text("#error")
    assert "POST" not in said and "robotctl" not in said, said
    assert sim.status()["navigation"]["state"] != "active"
    page.locator("#tabs button[data-tab=drive]").tap()
    screenshot(page, "phone-estop")
    page.answers.append(True)
    page.locator("#estop-release").tap()
    page.wait_for_selector("#estop-banner", state="hidden")
    assert sim.status()["estop"]["latched"] is False
    page.wait_for_function("document.getElementById('pad').getAttribute('aria-disabled') === 'false'", timeout=5000)
    page.locator("#tabs button[data-tab=places]").tap()
    page.locator("#places li[data-name=kitchen] button.go").tap()
    page.wait_for_function("document.getElementById('nav').dataset.state === 'active'", timeout=10000)
    assert page.inner_text("#error") == "", "a goal that went through clears the refusal before it"
    sim.post("/stop")


def uncovered(page, selector):
    """True when points near the element's corners and centre are on screen and a finger there touches it."""
    return page.evaluate("""(selector) => {
      const el = document.querySelector(selector), r = el.getBoundingClientRect();
      const at = (fx, fy) => [r.left + r.width * fx, r.top + r.height * fy];  // inside round corners too
      const points = [at(.2, .2), at(.8, .2), at(.2, .8), at(.8, .8), at(.5, .5)];
      return r.width > 0 && points.every(([x, y]) => {
        const hit = document.elementFromPoint(x, y);
        return hit && (el === hit || el.contains(hit));
      });
    }""", selector)


LANDSCAPE = dict(PHONE, viewport={"width": 844, "height": 390})


@pytest.mark.parametrize("device, name", [(DESKTOP, "desktop"), (LANDSCAPE, "phone-landscape")])
def test_wide_screens_show_map_and_panel_side_by_side(sim, browser, device, name):
    page = browser.open(sim.url + "/", device=device)
    live(page)
    page.wait_for_function("document.getElementById('map').dataset.imageRect")
    board, panel = canvas_box(page), page.locator("#panel").bounding_box()
    assert panel["x"] >= board["x"] + board["width"] - 1 and board["width"] > panel["width"]
    for control in ("#stop", "#pad", "#estop", "#gesture button[data-gesture=look]", "#fit"):
        assert uncovered(page, control), control + " is hidden or covered"
    screenshot(page, name)
    page.close()


SMALL_PHONE = dict(PHONE, viewport={"width": 360, "height": 640})


def test_a_small_phone_keeps_every_control_reachable(sim, browser):
    page = browser.open(sim.url + "/", device=SMALL_PHONE)
    live(page)
    page.wait_for_function("document.getElementById('map').dataset.imageRect")
    for control in ("#stop", "#pad", "#estop", "#fit", "#follow", "#mode", "#conn",
                    "#gesture button[data-gesture=go]", "#gesture button[data-gesture=look]"):
        assert uncovered(page, control), control + " is hidden or covered"
    assert canvas_box(page)["height"] >= 150, "room for the map"
    font = page.evaluate("parseFloat(getComputedStyle(document.querySelector('#places')).fontSize)")
    assert font >= 16, "text readable at arm's length"
    page.close()


def test_set_pose_mode_moves_the_robots_pose(sim, page):
    at_rest(sim)
    page.locator("#gesture button[data-gesture=pose]").tap()
    assert "where the robot really is" in page.inner_text("#hint")
    screen = Screen(page, sim)
    start = screen.screen(2.0, 0.5)  # free floor, away from where the robot stands
    finger = Finger(page, on_page(page, start))
    for step in range(1, 6):  # drag straight up: facing +y
        finger.move(on_page(page, (start[0], start[1] - 8 * step)))
    finger.lift()
    wx, wy = screen.world(*start)
    wait_for(lambda: math.hypot(sim.pose()["x"] - wx, sim.pose()["y"] - wy) <= screen.tolerance + 0.05, timeout=10,
             message="the robot's pose to move to the pressed point")
    assert angle_error(sim.pose()["yaw"], math.pi / 2) < 0.15
    assert sim.status()["navigation"]["state"] != "active", "a pose estimate is not a goal"
    page.wait_for_function("document.getElementById('map').dataset.gesture === 'go'")  # back to Go after one
    # Only the belief moved (the sim's robot stays where it stands): put it back where the robot is.
    assert sim.post("/pose", sim.status()["sim"]["true_pose"]).status_code == 200


def test_the_plan_is_drawn_while_the_robot_drives(sim, page):
    at_rest(sim)
    sim.post("/goto", {"name": "bedroom"})
    page.wait_for_function("Number(document.getElementById('map').dataset.planPoints) > 1", timeout=15000)
    screenshot(page, "phone-plan")
    sim.post("/stop")
    page.wait_for_function("Number(document.getElementById('map').dataset.planPoints) === 0", timeout=15000)


def test_a_goal_it_cannot_reach_says_why(sim, page):
    at_rest(sim)
    screen = Screen(page, sim)
    start = screen.screen(4.6, -1.5)  # the demo flat's locked store room
    finger = Finger(page, on_page(page, start))
    finger.move(on_page(page, (start[0] + 30, start[1])))
    finger.lift()
    page.wait_for_function("['aborted', 'rejected'].includes(document.getElementById('nav').dataset.state)",
                           timeout=30000)
    text = page.inner_text("#nav-text")
    message = sim.status()["navigation"]["message"]
    assert text.startswith("failed: ") and (message is None or message in text), (text, message)


@pytest.mark.parametrize("status, body", [
    (404, {"status": "error", "error": "not_found", "message": "No such endpoint."}),  # a server before /events
    (503, {"status": "error", "error": "too_many_streams", "message": "Every stream is taken."}),
])
def test_without_a_stream_the_page_polls_and_still_follows_the_robot(sim, browser, status, body):
    at_rest(sim)

    def no_stream(page):
        page.route("**/events", lambda route: route.fulfill(status=status, json=body))
    page = browser.open(sim.url + "/", before=no_stream)
    page.wait_for_function("document.body.dataset.connection === 'polling'", timeout=20000)
    assert page.inner_text("#conn") == "live (polling)"
    page.wait_for_function("document.getElementById('map').dataset.robotPx")
    before = robot_px(page)
    sim.post("/goto", {"name": "kitchen"})
    page.wait_for_function("document.getElementById('nav').dataset.state === 'active'", timeout=10000)
    page.wait_for_function("(b) => { const p = document.getElementById('map').dataset.robotPx.split(',');"
                           " return Math.hypot(p[0] - b[0], p[1] - b[1]) > 10; }", arg=before, timeout=20000)
    assert page.get_attribute("#map", "data-robot-stale") == "0"
    sim.post("/stop")
    page.close()


def test_the_event_parser_reads_events_however_the_bytes_are_cut(page):
    """The page's own SSE parser (live.js) on a stream cut mid-line, mid-CRLF, with comments and retry."""
    events = page.evaluate("""async () => {
      const {SseParser} = await import('/static/js/live.js');
      const got = [];
      const parser = new SseParser((type, data) => got.push([type, data]));
      const stream = 'retry: 2000\\n\\nevent: pose\\ndata: {"x": 1}\\n\\n: heartbeat\\n\\n' +
                     'event: mode\\r\\ndata: {"mode":\\r\\ndata: "idle"}\\r\\n\\r\\ndata: plain\\n\\n';
      for (const cut of [1, 2, 3, 5, 7, 11]) {
        for (let i = 0; i < stream.length; i += cut) parser.feed(stream.slice(i, i + cut));
      }
      return got;
    }""")
    once = [["pose", '{"x": 1}'], ["mode", '{"mode":\n"idle"}'], ["message", "plain"]]
    assert events == once * 6


def test_the_keyboard_drives_on_a_desktop_and_letting_go_stops(sim, browser):
    at_rest(sim)
    page = browser.open(sim.url + "/", device=DESKTOP)
    live(page)
    log = RequestLog(page)
    page.keyboard.down("ArrowUp")
    page.keyboard.down("ArrowLeft")  # forward and turning left: the right side faster
    wait_for(lambda: sim.status()["motors"]["right"] > sim.status()["motors"]["left"] >= 0, timeout=10,
             message="the arrow keys to drive the motors")
    page.wait_for_timeout(600)  # longer than the deadman: the page repeats, not the key's auto-repeat
    # Still driving (a machine too loaded to repeat in time lets the deadman stop the motors for a beat;
    # the next repeat drives them again, where a page that never repeats leaves them stopped).
    wait_for(lambda: sim.status()["motors"]["right"] > 0, timeout=5, message="the page to repeat the keys' command")
    page.keyboard.up("ArrowLeft")
    page.keyboard.up("ArrowUp")
    wait_for(lambda: log.calls("POST", "/stop"), timeout=5, message="a stop when the last key is let go")
    wait_for(lambda: sim.status()["motors"]["left"] == 0.0 and sim.status()["motors"]["right"] == 0.0, timeout=5,
             message="the motors stopped")
    page.close()
