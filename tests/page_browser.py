"""The phone page's test rig: Debian's chromium driven by Playwright, against a real ``--sim`` server.

No browser is downloaded (``playwright install`` is never run): Playwright's driver comes with the
pip package and drives ``/usr/bin/chromium``, with the flags that keep it from reaching for the
network this machine does not have. A page is opened as a phone would (390×844, touch, mobile).

``PageSim`` needs no browser (server-side tests use it, ``make test-debian`` too, which has no
Playwright); ``Browser`` imports Playwright when one is opened: browser-test modules
``pytest.importorskip("playwright")`` first.
"""

import math
import os
import shutil

import requests

from tests import overload
from tests.conftest import ROOT, ServerProcess, SimReads, free_port, stop_process, wait_for

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
PHONE = {"viewport": {"width": 390, "height": 844}, "has_touch": True, "is_mobile": True, "device_scale_factor": 1}
DESKTOP = {"viewport": {"width": 1280, "height": 800}}
SPEED_FACTOR = 4.0
DEFAULT_TIMEOUT = 30000  # ms: Playwright's own, for waits without a timeout of their own
DEMO_WAYPOINTS = os.path.join(ROOT, "config", "waypoints.demo.yaml")
# Pictures go to build/screenshots; PAGE_SCREENSHOTS=docs/images refreshes the ones docs/phone.md shows.
IMAGES = os.path.join(ROOT, os.environ.get("PAGE_SCREENSHOTS", os.path.join("build", "screenshots")))


class PageSim(SimReads, ServerProcess):
    """``flask-move-server --sim`` for the page: its own master, a copy of the demo waypoints, a token if asked."""

    def __init__(self, folder, token=None, port=0, extra_config="", world=None, speed_factor=SPEED_FACTOR):
        """``world``: the simulated world's map YAML (default: the demo flat)."""
        self.folder, self.token = folder, token
        self.master_uri = "http://127.0.0.1:{}".format(free_port())
        self.waypoints = folder / "waypoints.yaml"
        if not self.waypoints.exists():
            shutil.copy(DEMO_WAYPOINTS, str(self.waypoints))
        config = folder / "sim.yaml"
        world_line = "  map: {}\n".format(world) if world else ""
        config.write_text("sim:\n  speed_factor: {}\n{}{}".format(speed_factor, world_line, extra_config))
        env = {"ROS_MASTER_URI": self.master_uri, "ROS_HOME": str(folder), "ROS_LOG_DIR": str(folder / "log"),
               "ROS_IP": "127.0.0.1"}
        if token:
            env["FLASK_MOVE_SERVER_TOKEN"] = token
        super().__init__("--sim", "--config", str(config), "--host", "127.0.0.1", "--port", str(port), "--no-mdns",
                         "--waypoints", str(self.waypoints), env=env, start_timeout=60)
        wait_for(lambda: self.get("/health").json().get("move_base") == "ready", timeout=30, message="move_base")
        wait_for(lambda: self.pose() is not None, timeout=30, message="a pose from tf map -> base_link")

    @property
    def port(self):
        return int(self.url.rsplit(":", 1)[1])

    def headers(self):
        return {"Authorization": "Bearer " + self.token} if self.token else {}

    def get(self, path, timeout=10):
        return requests.get(self.url + path, headers=self.headers(), timeout=timeout)

    def post(self, path, body=None, timeout=10):
        return requests.post(self.url + path, json=body, headers=self.headers(), timeout=timeout)

    def put(self, path, body=None, timeout=10):
        return requests.put(self.url + path, json=body, headers=self.headers(), timeout=timeout)

    def delete(self, path, timeout=10):
        return requests.delete(self.url + path, headers=self.headers(), timeout=timeout)

    def close(self):
        stop_process(self.proc)


class Browser:
    """One headless chromium for a test module; ``open(url)`` gives a fresh phone (or desktop) page."""

    def __init__(self):
        if not os.path.exists(CHROMIUM):
            raise AssertionError("no {}: the browser tests drive Debian's chromium (make setup installs it: "
                                 "apt-get install chromium)".format(CHROMIUM))
        from playwright.sync_api import sync_playwright

        self._playwright = sync_playwright().start()
        self.browser = self._playwright.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS, headless=True)
        self.contexts = []

    def open(self, url, device=PHONE, answers=None, before=None):
        """A page at ``url``; ``page.answers``: replies to its prompt/confirm dialogs, in order, each used once.

        A string answers a prompt, True accepts a confirm, False (or nothing left) dismisses; every
        question asked is kept in ``page.asked``. ``before(page)`` runs before the page loads (routes).
        """
        context = self.browser.new_context(**device)
        context.set_default_timeout(DEFAULT_TIMEOUT * overload.time_scale())  # longer on a loaded machine
        self.contexts.append(context)
        page = context.new_page()
        page.asked = []
        page.answers = list(answers or [])
        page.errors = []
        page.on("pageerror", lambda error: page.errors.append(str(error)))

        def answer(dialog):
            page.asked.append(dialog.message)
            reply = page.answers.pop(0) if page.answers else False
            if reply is False:
                dialog.dismiss()
            else:
                dialog.accept(reply if isinstance(reply, str) else "")
        page.on("dialog", answer)
        if before:
            before(page)
        page.goto(url)
        return page

    def close(self):
        for context in self.contexts:
            context.close()
        self.browser.close()
        self._playwright.stop()


def live(page, timeout=20000):
    """Wait until the page says it is connected (the live stream, or polling where there is none)."""
    page.wait_for_function("['live', 'polling'].includes(document.body.dataset.connection)", timeout=timeout)


def on_the_map(browser, sim):
    """The page at ``sim``, live, with its map drawn: where most page tests start."""
    page = browser.open(sim.url + "/")
    live(page)
    page.wait_for_function("document.getElementById('map').dataset.imageRect")
    return page


def robot_px(page):
    """Where the page draws the robot: CSS pixels inside the map canvas, or None."""
    value = page.get_attribute("#map", "data-robot-px")
    return tuple(float(v) for v in value.split(",")) if value else None


def canvas_box(page):
    return page.locator("#map").bounding_box()


def screenshot(page, name):
    """A picture of the page as a test left it (NAME.png in IMAGES), for docs/phone.md."""
    os.makedirs(IMAGES, exist_ok=True)
    page.screenshot(path=os.path.join(IMAGES, name + ".png"))


def _touch(session, kind, point):
    session.send("Input.dispatchTouchEvent", {"type": kind, "touchPoints": [{"x": point[0], "y": point[1]}]})


def angle_error(a, b):
    return abs(math.atan2(math.sin(a - b), math.cos(a - b)))


class Finger:
    """One finger on the touch screen (CDP touch events, so the page sees pointerType "touch")."""

    def __init__(self, page, point):
        self.page = page
        self.session = page.context.new_cdp_session(page)
        self.point = point
        _touch(self.session, "touchStart", point)

    def move(self, point):
        self.point = point
        _touch(self.session, "touchMove", point)

    def lift(self):
        """Lift the finger where it rests, as a person does after a drag.

        A move and a lift in the same instant is a flick: Chrome starts a fling, and the next tap
        anywhere only stops that fling, with no click (a tap on a button after a drag did nothing,
        1 run in 2). So the finger rests a moment at its last point first.
        """
        self.page.wait_for_timeout(60)
        _touch(self.session, "touchMove", self.point)
        self.session.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": []})
        self.session.detach()


def centre(page, selector):
    box = page.locator(selector).bounding_box()
    return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2


def tap(page, selector):
    """A finger tap on the element (Playwright's tap: touch events at its centre)."""
    page.locator(selector).tap()


class RequestLog:
    """Every request the page sends from now on. Playwright's sync API hands events over only while
    it is called, so reading the log first lets it deliver what came (``page.wait_for_timeout``)."""

    def __init__(self, page):
        self.page = page
        self.requests = []
        page.on("request", lambda request: self.requests.append(request))

    def calls(self, method, path):
        self.page.wait_for_timeout(10)
        return [r for r in self.requests
                if r.method == method and "/" + r.url.split("/", 3)[-1].split("?")[0] == path]
