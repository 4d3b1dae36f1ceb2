"""The phone page's connection in a real browser: the token asked once, a restarted server found again.

A ``--sim`` server with a token. The page, opened as a phone, meets a 401, asks for the token once,
keeps it on the device (localStorage) and sends it only in the Authorization header, never in a URL.
Then the server is stopped: the page says "reconnecting" and refuses to act on what it last knew;
started again on the same port, the page is live again by itself, without asking again.
"""

import pytest

pytest.importorskip("playwright", reason="playwright is not installed (pip install -e '.[test]'; Debian lacks it)")

from tests.conftest import wait_for  # noqa: E402
from tests.page_browser import PageSim, RequestLog, live, screenshot  # noqa: E402

TOKEN = "page-token-5ee2"


@pytest.fixture(scope="module")
def server(tmp_path_factory):
    holder = {"sim": PageSim(tmp_path_factory.mktemp("page_token"), token=TOKEN)}
    yield holder
    holder["sim"].close()


@pytest.fixture(scope="module")
def page(server, browser):
    page = browser.open(server["sim"].url + "/", answers=[TOKEN])
    page.log = RequestLog(page)
    return page


def go_from_the_list(page, name):
    page.locator("#tabs button[data-tab=places]").tap()
    page.locator('#places li[data-name="{}"] button.go'.format(name)).tap()


def test_with_a_token_the_page_asks_once_and_works(server, page):
    sim = server["sim"]
    live(page)
    page.wait_for_selector("#places li[data-name=kitchen]", state="attached")
    go_from_the_list(page, "kitchen")
    wait_for(lambda: sim.status()["navigation"]["target"] == "kitchen", timeout=10, message="the goal sent")
    sim.post("/stop")
    assert len(page.asked) == 1 and "token" in page.asked[0]
    assert page.evaluate("localStorage.getItem('robotToken')") == TOKEN
    sent = page.log.requests
    assert sent and not [r.url for r in sent if TOKEN in r.url], "the token must never be in a URL"
    assert any(r.headers.get("authorization") == "Bearer " + TOKEN for r in sent)


def test_a_restarted_server_is_reconnected_to(server, page, tmp_path_factory):
    sim = server["sim"]
    live(page)
    port, folder = sim.port, sim.folder
    sim.close()
    page.wait_for_function("document.body.dataset.connection === 'reconnecting'", timeout=20000)
    assert page.inner_text("#conn").startswith("reconnecting")
    assert page.locator('#places li[data-name="sofa"] button.go').is_disabled(), "no goals on stale state"
    assert page.locator("#pad").get_attribute("aria-disabled") == "true"
    page.wait_for_function("document.getElementById('map').dataset.robotStale === '1'", timeout=5000)
    assert "not connected" in page.inner_text("#stale-note"), "the grey robot says why"
    screenshot(page, "phone-reconnecting")

    server["sim"] = sim = PageSim(folder, token=TOKEN, port=port)
    live(page, timeout=30000)
    page.wait_for_function("document.getElementById('map').dataset.robotStale === '0'", timeout=10000)
    go_from_the_list(page, "sofa")
    wait_for(lambda: sim.status()["navigation"]["target"] == "sofa", timeout=10, message="a goal after reconnecting")
    sim.post("/stop")
    assert len(page.asked) == 1, "the token is asked for once, not again after reconnecting"
    assert page.errors == []


def test_a_dismissed_token_question_says_so_and_the_token_button_asks_again(server, browser):
    page = browser.open(server["sim"].url + "/", answers=[False])  # another phone: the question dismissed
    page.wait_for_function("document.body.dataset.connection === 'unauthorised'", timeout=20000)
    assert page.inner_text("#conn") == "token needed" and len(page.asked) == 1
    page.wait_for_timeout(1500)
    assert len(page.asked) == 1, "not asked again on every retry"
    page.answers.append(TOKEN)
    page.locator("#tabs button[data-tab=maps]").tap()
    page.locator("#token").tap()
    live(page)
    page.wait_for_selector("#places li[data-name=kitchen]", state="attached")
    page.close()
