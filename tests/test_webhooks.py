"""Webhooks: JSON POSTs of happenings to real local HTTP receivers (http.server in a thread).

The body field by field from a real goal (rospy, actionlib, the scripted move_base), retries and
their back-off, no redirect followed, no Authorization header even when the server has a token,
a receiver that never answers delays neither the robot nor the shutdown, a full queue drops and
counts; the config refuses a webhook without an http(s) URL.
"""

import contextlib
import datetime
import json
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest

from flask_move_server import __version__, config
from flask_move_server.app import cli
from flask_move_server.config import WebhookConfig
from flask_move_server.core.errors import ConfigError
from flask_move_server.core.events import EventBus
from flask_move_server.core.happenings import Happenings
from flask_move_server.mqtt.webhooks import Webhooks
from flask_move_server.web import create_app
from tests.conftest import wait_for
from tests.hostile import HostileReceiver
from tests.standins.move_base import HOLD_X

FAST = (0.05, 0.1)  # back-off between tries in tests (1 s, 2 s in the server)


class Receiver:
    """A real HTTP server on 127.0.0.1, port 0: keeps every request; answers as ``answers`` says.

    ``answers``: a list of status codes used one per request (the last one for the rest);
    ``hang``: never answer (until the test ends); ``redirect``: 302 to ``/elsewhere``.
    """

    def __init__(self, answers=(200,), hang=False):
        self.requests = []
        self.answers = list(answers)
        self.hang = hang
        self.released = threading.Event()
        self._lock = threading.Lock()
        receiver = self

        class Handler(BaseHTTPRequestHandler):
            def do_POST(self):
                length = int(self.headers.get("Content-Length") or 0)
                body = self.rfile.read(length)
                with receiver._lock:
                    receiver.requests.append({"path": self.path, "headers": dict(self.headers), "body": body,
                                              "at": time.monotonic()})
                    code = receiver.answers.pop(0) if len(receiver.answers) > 1 else receiver.answers[0]
                if receiver.hang:
                    receiver.released.wait(30)
                    return
                self.send_response(code)
                if code in (301, 302, 307, 308):
                    self.send_header("Location", "/elsewhere")
                self.send_header("Content-Length", "0")
                self.end_headers()

            def log_message(self, *args):
                pass

        self._server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self._server.daemon_threads = True
        self._thread = threading.Thread(target=self._server.serve_forever, name="test-receiver", daemon=True)
        self._thread.start()
        self.url = "http://127.0.0.1:{}/api/webhook/secret-id".format(self._server.server_address[1])

    def bodies(self):
        with self._lock:
            return [json.loads(r["body"]) for r in self.requests]

    def close(self):
        self.released.set()
        self._server.shutdown()
        self._server.server_close()
        self._thread.join(5)


@pytest.fixture
def receivers():
    made = []

    def make(**kw):
        made.append(Receiver(**kw))
        return made[-1]

    yield make
    for receiver in made:
        receiver.close()


class Teller:
    """A stand-in for Happenings where only the webhooks' side is tested: ``tell`` as a happening would."""

    def __init__(self):
        self._listeners = []

    def listen(self, callback):
        self._listeners.append(callback)

    def tell(self, name, data):
        for callback in self._listeners:
            callback(name, data)


@contextlib.contextmanager
def webhooks(hooks, teller=None, **kw):
    kw.setdefault("backoff", FAST)
    hooks_ = Webhooks(hooks, "robot", teller if teller is not None else Teller(), **kw)
    try:
        yield hooks_
    finally:
        hooks_.close()


def hook(url, *events):
    return WebhookConfig(url=url, events=list(events) if events else list(config.WEBHOOK_EVENTS))


# the body, from a real goal ---------------------------------------------------------------------


@pytest.fixture
def happenings(ready_robot, bus):
    told = Happenings(ready_robot, bus)
    yield told
    told.close()


def test_an_arrival_is_posted_as_json_field_by_field(client, ready_robot, happenings, receivers):
    receiver = receivers()
    with webhooks([hook(receiver.url)], happenings) as sent:
        before = datetime.datetime.now(datetime.timezone.utc)
        assert client.post("/goto", json={"name": "kitchen"}).status_code == 202
        seq = ready_robot.navigator.status()["goal_id"]
        wait_for(lambda: receiver.requests, message="the webhook's POST")
        (request,) = receiver.requests
        assert request["path"] == "/api/webhook/secret-id"
        assert request["headers"]["Content-Type"] == "application/json"
        assert request["headers"]["User-Agent"] == "flask-move-server/{} (webhooks)".format(__version__)
        body = json.loads(request["body"])
        assert list(body)[:3] == ["event", "robot", "at"]
        assert body == {"event": "arrived", "robot": "robot", "at": body["at"], "target": "kitchen",
                        "goal": {"x": 1.23, "y": 4.56, "yaw": 0.79}, "goal_id": seq}
        at = datetime.datetime.fromisoformat(body["at"])
        assert at.utcoffset() == datetime.timedelta(0) and before - datetime.timedelta(seconds=1) <= at
        assert at <= datetime.datetime.now(datetime.timezone.utc)
        wait_for(lambda: sent.status()["sent"] == 1, message="the POST counted")
        assert sent.status() == {"sent": 1, "failed": 0, "dropped": 0, "queued": 0}


def test_the_bodies_of_run_done_estop_and_explore_done(ready_robot, bus, happenings, receivers):
    receiver = receivers()
    with webhooks([hook(receiver.url)], happenings):
        run = {"id": 3, "route": "patrol", "state": "succeeded", "visited": [{"name": "kitchen"}]}
        bus.publish("run", run)
        ready_robot.engage_estop("button")
        ready_robot.release_estop()
        bus.publish("explore", {"state": "exploring", "save_as": "flat", "started": "s"})
        bus.publish("explore", {"state": "done", "save_as": "flat", "started": "s", "map": "flat"})
        bodies = wait_for(lambda: len(receiver.requests) == 3 and receiver.bodies(), message="three POSTs")
    for body in bodies:
        assert body.pop("robot") == "robot" and body.pop("at")
    assert bodies == [dict(run, event="run_done"), {"event": "estop", "source": "button"},
                      {"event": "explore_done", "state": "done", "save_as": "flat", "started": "s", "map": "flat"}]


def test_a_canceled_goal_posts_nothing(client, ready_robot, store, move_base, happenings, receivers):
    from flask_move_server.waypoints import make_waypoint

    receiver = receivers()
    store.put(make_waypoint("far", HOLD_X, 0.0, 0.0))
    with webhooks([hook(receiver.url)], happenings) as sent:
        assert client.post("/goto", json={"name": "far"}).status_code == 202
        wait_for(lambda: move_base.executing, message="move_base driving the goal")
        assert client.post("/stop").status_code == 200
        wait_for(lambda: ready_robot.navigator.status()["state"] == "canceled", message="the goal canceled")
        time.sleep(0.5)
        assert receiver.requests == [] and sent.status()["sent"] == 0


# delivery -------------------------------------------------------------------------------------


def test_two_failures_then_a_success_is_three_tries_and_one_delivery(receivers):
    receiver = receivers(answers=[500, 503, 204])
    teller = Teller()
    with webhooks([hook(receiver.url)], teller) as sent:
        teller.tell("estop", {"source": "api"})
        wait_for(lambda: sent.status()["sent"] == 1, message="the third try delivered")
        assert sent.status() == {"sent": 1, "failed": 0, "dropped": 0, "queued": 0}
    times = [r["at"] for r in receiver.requests]
    assert len(times) == 3 and len({r["body"] for r in receiver.requests}) == 1  # the same body each time
    assert times[1] - times[0] >= FAST[0] and times[2] - times[1] >= FAST[1]


def test_a_receiver_that_keeps_failing_gets_three_tries_and_a_counted_failure(receivers, caplog):
    receiver = receivers(answers=[500])
    teller = Teller()
    with webhooks([hook(receiver.url)], teller) as sent:
        teller.tell("estop", {"source": "api"})
        wait_for(lambda: sent.status()["failed"] == 1, message="given up")
        assert len(receiver.requests) == 3 and sent.status()["sent"] == 0
    assert "HTTP 500" in caplog.text and "secret-id" not in caplog.text  # the URL's path is the secret


def test_a_client_error_is_not_tried_again(receivers):
    receiver = receivers(answers=[404])
    teller = Teller()
    with webhooks([hook(receiver.url)], teller) as sent:
        teller.tell("estop", {"source": "api"})
        wait_for(lambda: sent.status()["failed"] == 1, message="given up")
        time.sleep(0.3)
        assert len(receiver.requests) == 1


def test_a_redirect_is_not_followed(receivers, caplog):
    receiver = receivers(answers=[302])
    teller = Teller()
    with webhooks([hook(receiver.url)], teller) as sent:
        teller.tell("estop", {"source": "api"})
        wait_for(lambda: sent.status()["failed"] == 1, message="given up")
        time.sleep(0.3)
    assert [r["path"] for r in receiver.requests] == ["/api/webhook/secret-id"]
    assert "redirect" in caplog.text


def test_a_refused_connection_is_a_counted_failure_without_the_path_in_the_log(receivers, caplog):
    from tests.conftest import free_port

    teller = Teller()
    url = "http://127.0.0.1:{}/api/webhook/secret-id".format(free_port())
    with webhooks([hook(url)], teller) as sent:
        teller.tell("estop", {"source": "api"})
        wait_for(lambda: sent.status()["failed"] == 1, message="given up")
    assert "not delivered (3 tries)" in caplog.text and "secret-id" not in caplog.text


def test_only_the_events_a_webhook_lists_are_posted(receivers):
    estops, everything = receivers(), receivers()
    teller = Teller()
    with webhooks([hook(estops.url, "estop"), hook(everything.url)], teller) as sent:
        for name in ("arrived", "failed", "run_done", "explore_done", "estop"):
            teller.tell(name, {})
        wait_for(lambda: sent.status()["sent"] == 6, message="six POSTs")
    assert [b["event"] for b in estops.bodies()] == ["estop"]
    assert [b["event"] for b in everything.bodies()] == ["arrived", "failed", "run_done", "explore_done", "estop"]


def test_a_full_queue_drops_the_newest_and_counts_with_one_warning(receivers, caplog):
    receiver = receivers(hang=True)
    teller = Teller()
    with webhooks([hook(receiver.url)], teller, queue_size=2, timeout=1.0, close_wait=0.2) as sent:
        teller.tell("estop", {"n": 0})
        wait_for(lambda: receiver.requests, message="the first POST under way")
        for n in range(1, 6):
            teller.tell("estop", {"n": n})  # 1, 2 queued; 3, 4, 5 dropped
        assert sent.status() == {"sent": 0, "failed": 0, "dropped": 3, "queued": 2}
    drops = [r for r in caplog.records if "dropped" in r.getMessage() and r.levelname == "WARNING"]
    # Told once, with the count so far, not once per drop (the URL in it may hold any digits: its port).
    assert len(drops) == 1 and drops[0].getMessage().endswith(", 1 dropped so far")
    assert any("2 not sent" in r.getMessage() for r in caplog.records)


# a receiver that never answers ------------------------------------------------------------------


def test_a_hanging_receiver_delays_neither_the_robot_nor_close(robot_config, ready_robot, store, happenings,
                                                               receivers):
    hanging, other = receivers(hang=True), receivers()
    app = create_app(robot_config, ready_robot, store, token="s3cret")
    client = app.test_client()
    auth = {"Authorization": "Bearer s3cret"}
    sent = Webhooks([hook(hanging.url), hook(other.url)], "robot", happenings, backoff=FAST, timeout=1.0,
                    close_wait=0.5)
    try:
        for _ in range(3):
            assert client.post("/goto", json={"name": "kitchen"}, headers=auth).status_code == 202
            wait_for(lambda: ready_robot.navigator.status()["state"] == "succeeded", message="arrived")
        started = time.monotonic()
        assert client.post("/stop", headers=auth).status_code == 200
        assert time.monotonic() - started < 2.0  # a stop that waited for a POST would take the 1 s timeout x 3
        # A worker per receiver: the other one gets its POSTs while the hanging one's tries wait out.
        wait_for(lambda: len(other.requests) >= 3, timeout=2, message="the other webhook's three POSTs")
    finally:
        started = time.monotonic()
        sent.close()
        closed_in = time.monotonic() - started
    assert closed_in < 1.5
    for request in hanging.requests + other.requests:
        assert not {"authorization", "proxy-authorization", "cookie"} & {k.lower() for k in request["headers"]}
        assert "s3cret" not in json.dumps(request["headers"]) + str(request["body"], "utf-8")


def test_happenings_listeners_return_at_once_with_a_hanging_receiver(receivers):
    receiver = receivers(hang=True)
    teller = Teller()
    with webhooks([hook(receiver.url)], teller, timeout=1.0, close_wait=0.2):
        started = time.monotonic()
        for _ in range(50):
            teller.tell("arrived", {"target": "kitchen"})
        assert time.monotonic() - started < 0.2


def test_close_returns_promptly_while_backing_off(receivers):
    receiver = receivers(answers=[500])
    teller = Teller()
    sent = Webhooks([hook(receiver.url)], "robot", teller, backoff=(30.0, 30.0))
    teller.tell("estop", {"source": "api"})
    wait_for(lambda: receiver.requests, message="the first try")
    started = time.monotonic()
    sent.close()
    assert time.monotonic() - started < 1.0
    teller.tell("estop", {"source": "api"})  # after close: not queued
    assert sent.status()["queued"] == 0 and len(receiver.requests) == 1


# wiring and config ------------------------------------------------------------------------------


def test_the_server_wires_webhooks_only_when_the_config_lists_some(robot_config, ready_robot, receivers):
    receiver = receivers()
    robot_config.webhooks = [hook(receiver.url, "estop")]
    robot_config.mdns.hostname = "rover"
    server = cli.Server(robot_config)
    server.events = EventBus()
    with contextlib.ExitStack() as stack:
        assert isinstance(server._build_happenings(stack, ready_robot), Happenings)
        ready_robot.engage_estop("api")
        ready_robot.release_estop()
        wait_for(lambda: receiver.requests, message="the e-stop's POST")
    assert receiver.bodies()[0]["robot"] == "rover"
    server.events.close()
    without = cli.Server(config.Config())
    without.events = EventBus()
    with contextlib.ExitStack() as stack:
        without._build_happenings(stack, ready_robot)
        assert not any(t.name == "webhooks" for t in threading.enumerate())
    without.events.close()


@pytest.mark.parametrize("entry, reason", [
    ("- url: ''", "must be an http:// or https:// URL"),
    ("- events: [arrived]", "missing"),
    ("- url: file:///etc/passwd", "must be an http:// or https:// URL"),
    ("- url: ftp://hub.lan/x", "must be an http:// or https:// URL"),
    ("- url: http://user:pw@hub.lan/x", "no user:password@"),
    ("- url: http://hub.lan/x\n    events: [arrived, charged]", "must be one of"),
])
def test_the_config_refuses_a_webhook_without_an_http_url(tmp_path, entry, reason):
    path = tmp_path / "robot.yaml"
    path.write_text("webhooks:\n  " + entry + "\n")
    with pytest.raises(ConfigError) as refused:
        config.load(str(path))
    assert "webhooks[0]." in str(refused.value) and reason in str(refused.value)


def test_the_config_takes_http_and_https_webhooks(tmp_path):
    path = tmp_path / "robot.yaml"
    path.write_text("webhooks:\n  - url: https://hub.lan:8123/api/webhook/robot\n"
                    "  - url: http://10.0.0.5/hook\n    events: [estop]\n")
    loaded = config.load(str(path)).webhooks
    assert [(h.url, h.events) for h in loaded] == [
        ("https://hub.lan:8123/api/webhook/robot", list(config.WEBHOOK_EVENTS)), ("http://10.0.0.5/hook", ["estop"])]


def test_webhooks_built_in_code_refuse_an_empty_url():
    with pytest.raises(ConfigError, match=r"webhooks\[0\]\.url"):
        Webhooks([WebhookConfig()], "robot", Teller())



# hostile receivers (issue 34) ------------------------------------------------------------------


def test_an_endless_answer_is_not_read(receivers):
    """The status counts, the body is never read: a receiver streaming for ever once took the robot's
    memory to 3 GB. The POST is delivered and the connection closed after the status line."""
    endless = HostileReceiver()
    teller = Teller()
    try:
        with webhooks([hook(endless.url)], teller) as sent:
            teller.tell("estop", {"source": "api"})
            wait_for(lambda: sent.status()["sent"] == 1, timeout=5, message="delivered")
            time.sleep(0.5)
            assert endless.sent < 8 * 2 ** 20  # what the kernel's buffers took before the robot closed it
            assert endless.connections == 1
    finally:
        endless.close()


def test_a_trickling_receiver_gets_a_deadline_per_try_and_delays_no_other(receivers, caplog):
    """A byte every 0.3 s keeps each read within its timeout: the try as a whole has 1 s here (5 s in the
    server), then it is tried again, given up after three; another receiver is served meanwhile."""
    trickler, other = HostileReceiver(trickle=0.3), receivers()
    teller = Teller()
    try:
        with webhooks([hook(trickler.url), hook(other.url)], teller, timeout=1.0) as sent:
            started = time.monotonic()
            teller.tell("estop", {"source": "api"})
            wait_for(lambda: len(other.requests) == 1, timeout=1, message="the other receiver served at once")
            wait_for(lambda: sent.status()["failed"] == 1, timeout=6, message="the trickler given up")
            assert time.monotonic() - started < 1.0 * 3 + sum(FAST) + 1.0
        assert "no answer within 1 s" in caplog.text and "secret-id" not in caplog.text
    finally:
        trickler.close()


def test_a_signed_webhook_carries_the_hmac_of_its_body(receivers, tmp_path):
    import hashlib
    import hmac

    signed, plain, from_file = receivers(), receivers(), receivers()
    (tmp_path / "secret").write_text("file secret\n")
    teller = Teller()
    hooks = [WebhookConfig(url=signed.url, secret="s3cr3t ünicode"), hook(plain.url),
             WebhookConfig(url=from_file.url, secret_file=str(tmp_path / "secret"))]
    with webhooks(hooks, teller) as sent:
        teller.tell("estop", {"source": "api"})
        wait_for(lambda: sent.status()["sent"] == 3, message="three POSTs")
    for receiver, secret in ((signed, "s3cr3t ünicode"), (from_file, "file secret")):
        request = receiver.requests[0]
        expected = "sha256=" + hmac.new(secret.encode(), request["body"], hashlib.sha256).hexdigest()
        assert request["headers"]["X-Robot-Signature-256"] == expected
    assert "X-Robot-Signature-256" not in plain.requests[0]["headers"]


def test_a_secret_given_twice_or_unreadable_is_refused_at_start(tmp_path):
    with pytest.raises(ConfigError, match="not both"):
        Webhooks([WebhookConfig(url="http://hub.lan/x", secret="a", secret_file=str(tmp_path / "s"))], "r", Teller())
    with pytest.raises(ConfigError, match="cannot read the webhook's secret"):
        Webhooks([WebhookConfig(url="http://hub.lan/x", secret_file=str(tmp_path / "missing"))], "r", Teller())


def test_a_url_whose_secret_path_needs_encoding_never_reaches_the_log(caplog):
    from tests.conftest import free_port

    teller = Teller()
    url = "http://127.0.0.1:{}/api/webhook/s3cr%C3%A9t ünïcode?token=hidden".format(free_port())
    with webhooks([WebhookConfig(url=url.replace(" ", "%20"))], teller) as sent:
        teller.tell("estop", {"source": "api"})
        wait_for(lambda: sent.status()["failed"] == 1, message="given up")
    assert "not delivered" in caplog.text
    for secret in ("s3cr", "%C3", "nïcode", "token", "hidden", "webhook/"):
        assert secret not in caplog.text
