"""A property-based fuzz run of the whole API, from its own ``/openapi.json``, against a real server.

schemathesis turns the description into requests, valid ones (positive) and ones that break it on
purpose (negative). Each goes over HTTP to the product's own server (http/server.py, which answers
in JSON even what it refuses before the app) serving the real robot (rospy, actionlib, a scripted
move_base, no motors: backend ``none``) of this test only, with its own ROS names and waypoints
file, so nothing it does reaches another test. Whatever comes, the server never answers 5xx, every
error is the JSON error shape, and a valid request gets a status the description lists. Bounded:
a fixed number of examples per operation, derandomized so every run sends the same ones.

Needs schemathesis (the ``test`` extra: 4.x, or 3.x where Python is older than 4.x supports);
``make test-debian`` runs on Debian's packages without it and skips this test.
"""

import pytest
import requests

from tests.fake_explorer import FakeExplorer
from tests.test_http_server import hardened

schemathesis = pytest.importorskip(
    "schemathesis", reason="schemathesis is not installed (pip install -e '.[test]'; Debian does not package it)")
hypothesis = pytest.importorskip("hypothesis")

EXAMPLES = 30
TOKEN = "fuzz-token"
LAST = ("/estop/release", "/estop")  # the e-stop last: once latched, goals and teleop only answer 409


@pytest.fixture
def fuzzed_server(robot_config, ready_robot, store, tmp_path):
    """The server the product runs (http/server.py) on a free port, for the real robot of this test,
    with its run executor (routes and runs) as cli builds it, and an explorer (the fake one: the
    web layer's checks are what is fuzzed here)."""
    from flask_move_server.missions.executor import RunExecutor
    from flask_move_server.missions.history import RunHistory
    from flask_move_server.web import create_app

    robot_config.server.port = 0
    robot_config.navigation.max_wait = 0.5  # a valid /goto with "wait" holds a request at most this long
    runs = RunExecutor(ready_robot, store, RunHistory(str(tmp_path / "runs.json")))
    ready_robot.runs = runs
    explorer = FakeExplorer(estop=ready_robot.estop)
    app = create_app(robot_config, ready_robot, store, token=TOKEN, runs=runs, explorer=explorer)
    try:
        with hardened(app, robot_config.server) as (_, url):
            yield url
    finally:
        runs.close()
        explorer.close()


@pytest.mark.timeout(240)
def test_no_request_makes_the_server_fail_or_answer_anything_but_json_errors(fuzzed_server):
    document = requests.get(fuzzed_server + "/openapi.json", timeout=10).json()
    schema = _load(document)
    operations = [(path, method) for path, ops in document["paths"].items() for method in ops]
    for path, method in sorted(operations, key=lambda op: (LAST.index(op[0]) if op[0] in LAST else -1, op)):
        documented = set(document["paths"][path][method]["responses"])
        for negative in (False, True):
            _fuzz(schema[path][method.upper()], fuzzed_server, documented, negative)


def _fuzz(operation, url, documented, negative):
    strategy = _strategy(operation, negative)
    if strategy is None:
        return
    session = requests.Session()

    @hypothesis.settings(max_examples=EXAMPLES, deadline=None, database=None, derandomize=True,
                         suppress_health_check=list(hypothesis.HealthCheck), print_blob=False)
    @hypothesis.given(case=strategy)
    def run(case):
        # Sent with requests itself: the answer is a requests.Response in schemathesis 3 and 4 alike.
        request = case.as_transport_kwargs(base_url=url, headers={"Authorization": "Bearer " + TOKEN})
        with session.request(**request, timeout=10, stream=True) as response:  # GET /events never ends
            _check(case, response, documented, negative)

    try:
        run()
    except hypothesis.errors.Unsatisfiable:
        assert negative, "no valid request could be made for {} {}".format(operation.method, operation.path)
        # nothing in this operation can be made invalid (a path parameter any text fits, say)
    finally:
        session.close()


def _check(case, response, documented, negative):
    streamed = response.headers.get("Content-Type", "").startswith("text/event-stream")
    text = "(an event stream)" if streamed else response.text[:300]
    said = "{} {} -> {}: {}".format(case.method, case.formatted_path, response.status_code, text)
    assert response.status_code < 500, said
    if response.status_code >= 400:
        assert response.headers.get("Content-Type") == "application/json; charset=utf-8", said
        body = response.json()
        assert body["status"] == "error" and body["error"] and body["message"], said
    if not negative:
        assert str(response.status_code) in documented, said


def _load(document):
    """The schema object, in schemathesis 4 (``schemathesis.openapi``) or 3 (``schemathesis.from_dict``)."""
    openapi = getattr(schemathesis, "openapi", None)
    if openapi is not None and hasattr(openapi, "from_dict"):
        return openapi.from_dict(document)
    return schemathesis.from_dict(document)


def _strategy(operation, negative):
    """Cases for ``operation``, valid or not; None when it has nothing to make invalid (no body, no parameters)."""
    if negative and "requestBody" not in _raw(operation) and not _raw(operation).get("parameters"):
        return None
    modes = getattr(schemathesis, "GenerationMode", None)
    if modes is not None:  # schemathesis 4
        return operation.as_strategy(modes.NEGATIVE if negative else modes.POSITIVE)
    methods = schemathesis.DataGenerationMethod  # schemathesis 3
    return operation.as_strategy(data_generation_method=methods.negative if negative else methods.positive)


def _raw(operation):
    return operation.definition.raw
