"""Places named in the owner's language on the phone page (issue 22, item 6), in a real browser.

A phone (390×844, touch) against a real ``--sim`` server: "Küche" typed in Places → Mark here (as a
Mac keyboard may send it, decomposed) and "Mum's room" given to a press on the map in Mark mode go
to the server, into the waypoints file readable, and back to the page's list and the map's labels
as typed; marking "Küche" again asks before replacing it; a bad name is refused in words that
quote it as typed. The labels are read from what the page asked its canvas to write.
"""

import unicodedata

import pytest
import requests

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from tests.conftest import wait_for  # noqa: E402
from tests.page_browser import DESKTOP, PHONE, Finger, PageSim, live, screenshot  # noqa: E402
from tests.test_page import Screen, at_rest, on_page  # noqa: E402

NFD_KUCHE = unicodedata.normalize("NFD", "Küche")
LANDSCAPE = dict(PHONE, viewport={"width": 844, "height": 390})
# Every text the page writes on its canvases, kept in the page: what the map's labels say.
CANVAS_TEXTS = """
window.canvasTexts = [];
const fillText = CanvasRenderingContext2D.prototype.fillText;
CanvasRenderingContext2D.prototype.fillText = function (text, ...rest) {
  window.canvasTexts.push(String(text));
  return fillText.call(this, text, ...rest);
};
"""


@pytest.fixture(scope="module")
def sim(tmp_path_factory):
    server = PageSim(tmp_path_factory.mktemp("page_names"))
    yield server
    server.close()


def open_page(sim, browser, device=PHONE):
    page = browser.open(sim.url + "/", device=device, before=lambda p: p.add_init_script(CANVAS_TEXTS))
    live(page)
    page.wait_for_function("document.getElementById('map').dataset.imageRect")
    return page


def labels_drawn(page, *names):
    """Wait until the map labels each of ``names`` with the name as typed (the labels the page drew,
    as it publishes them in the canvas's data-labels, and the text it wrote on the canvas)."""
    page.evaluate("() => { window.canvasTexts.length = 0; }")
    page.wait_for_function("""(names) => {
      const drawn = JSON.parse(document.getElementById('map').dataset.labels || '[]');
      return names.every((n) => drawn.some((l) => l.name === n && l.text === n) && window.canvasTexts.includes(n));
    }""", arg=list(names), timeout=10000)


def test_a_place_named_in_the_owners_language_goes_page_server_file_page_as_typed(sim, browser):
    at_rest(sim)
    page = open_page(sim, browser)
    page.locator("#tabs button[data-tab=places]").tap()
    page.fill("#newname", NFD_KUCHE)  # typed on a Mac: u + a combining diaeresis
    page.locator("#mark-form button").tap()
    row = page.wait_for_selector('#places li[data-name="Küche"]')
    assert row.query_selector("button.go").inner_text() == "Küche"
    assert "  Küche: [" in sim.waypoints.read_text(encoding="utf-8")

    page.answers.append("Mum's room")  # the name asked for after a press-and-drag in Mark mode
    page.locator("#gesture button[data-gesture=mark]").tap()
    start = Screen(page, sim).screen(2.0, 0.5)
    finger = Finger(page, on_page(page, start))
    finger.move(on_page(page, (start[0] + 40, start[1])))
    finger.lift()
    row = page.wait_for_selector('#places li[data-name="Mum\'s room"]')
    assert row.query_selector("button.go").inner_text() == "Mum's room"
    assert '  "Mum\'s room": [' in sim.waypoints.read_text(encoding="utf-8")
    page.locator("#gesture button[data-gesture=go]").tap()
    labels_drawn(page, "Küche", "Mum's room")
    row.scroll_into_view_if_needed()
    screenshot(page, "phone-names")
    assert page.errors == []
    page.close()

    again = open_page(sim, browser)  # a fresh page: the names as the server keeps them
    again.locator("#tabs button[data-tab=places]").tap()
    names = [li.get_attribute("data-name") for li in again.query_selector_all("#places li")]
    assert "Küche" in names and "Mum's room" in names, names
    labels_drawn(again, "Küche", "Mum's room")
    again.close()


def test_marking_a_name_typed_differently_but_the_same_asks_before_replacing(sim, browser):
    requests.put(sim.url + "/waypoints/K%C3%BCche", json={"x": 1.0, "y": 0.5, "yaw": 0.0}, timeout=10)
    page = open_page(sim, browser)
    page.locator("#tabs button[data-tab=places]").tap()
    page.wait_for_selector('#places li[data-name="Küche"]')
    before = sim.waypoints.read_bytes()
    page.answers.append(False)  # "Replace the place Küche?" no
    page.fill("#newname", NFD_KUCHE)
    page.locator("#mark-form button").tap()
    wait_for(lambda: page.wait_for_timeout(20) or page.asked, timeout=5, message="the replace question")
    assert page.asked == ["Replace the place Küche?"]
    assert sim.waypoints.read_bytes() == before
    page.close()


def test_a_bad_name_is_refused_in_words_that_quote_it_as_typed(sim, browser):
    page = open_page(sim, browser)
    page.locator("#tabs button[data-tab=places]").tap()
    before = sim.waypoints.read_bytes()
    page.fill("#newname", "Küche/2")
    page.locator("#mark-form button").tap()
    page.wait_for_function("document.getElementById('error').textContent.includes('Küche/2')", timeout=10000)
    said = page.inner_text("#error")
    assert "'/' is not allowed" in said and "\\u00fc" not in said, said
    assert sim.waypoints.read_bytes() == before
    screenshot(page, "phone-names-refused")
    page.close()


@pytest.mark.parametrize("device, name", [(LANDSCAPE, "phone-landscape-names"), (DESKTOP, "desktop-names")])
def test_the_labels_in_other_screens(sim, browser, device, name):
    """Placed apart from the dock and the robot: a label with no room is left off (the list has it)."""
    for path, x, y in (("K%C3%BCche", 2.0, 0.5), ("Mum's%20room", 2.5, 1.5)):
        requests.put(sim.url + "/waypoints/" + path, json={"x": x, "y": y, "yaw": 0.0}, timeout=10)
    page = open_page(sim, browser, device)
    labels_drawn(page, "Küche", "Mum's room")
    screenshot(page, name)
    page.close()
