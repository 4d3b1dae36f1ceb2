"""Talking to a robot's HTTP API with requests: timeouts, tokens, one error per failure.

Shared by ``robotctl`` and ``record-waypoints`` (which saves through the
server when one answers). Every failure becomes a :class:`ClientError`
carrying one readable sentence and the exit status of its kind, so the
command-line tools print one line and exit, never a traceback.
"""

import json
import socket
import unicodedata
from urllib.parse import quote, urlsplit, urlunsplit

import requests

from flask_move_server.core.errors import ClientError

DEFAULT_URL = "http://robot.local:5000"
DEFAULT_TIMEOUT = 5.0


class ExitStatus:
    """robotctl's exit statuses: one per failure kind a script may want to tell apart."""

    OK = 0
    ERROR = 1  # the robot refused the request (bad input, conflicting state)
    USAGE = 2  # bad command line (argparse)
    UNREACHABLE = 3  # no robot answers at the URL
    UNAUTHORIZED = 4  # token missing or wrong
    NOT_FOUND = 5  # unknown waypoint
    UNAVAILABLE = 6  # the robot answers but ROS or move_base does not
    ABORTED = 10  # goto --wait: move_base gave up (no path, stuck)
    CANCELED = 11  # goto --wait: the goal was canceled or replaced
    TIMEOUT = 12  # goto --wait: still moving when --timeout ran out
    REJECTED = 13  # goto --wait: move_base refused the goal
    INTERRUPTED = 130  # Ctrl-C


_BY_HTTP_STATUS = {
    401: ExitStatus.UNAUTHORIZED,
    404: ExitStatus.NOT_FOUND,
    503: ExitStatus.UNAVAILABLE,
}


def waypoint_path(name):
    """The API path of waypoint ``name`` (spaces and the like escaped)."""
    return name_path("/waypoints/", name)


def name_path(prefix, name):
    """``prefix`` and ``name`` in NFC, percent-encoded as UTF-8 ("Küche": ``K%C3%BCche``, whatever
    the terminal composed), with nothing left that a URL would read as a separator."""
    return prefix + quote(unicodedata.normalize("NFC", name), safe="")


class RobotClient:
    """One robot's API at ``url``; every request has a timeout."""

    def __init__(self, url=DEFAULT_URL, token=None, timeout=DEFAULT_TIMEOUT):
        self.url = url.rstrip("/")
        self.token = token
        self.timeout = timeout
        self._session = requests.Session()
        self._resolved = False

    def get(self, path, **kw):
        return self.request("GET", path, **kw)

    def post(self, path, body=None, **kw):
        return self.request("POST", path, body, **kw)

    def put(self, path, body=None, **kw):
        return self.request("PUT", path, body, **kw)

    def patch(self, path, body=None, **kw):
        return self.request("PATCH", path, body, **kw)

    def delete(self, path, **kw):
        return self.request("DELETE", path, **kw)

    def request(self, method, path, body=None, timeout=None):
        """Send one request; the JSON answer (None when empty), or ClientError."""
        try:
            response = self._send(method, path, body, timeout)
        except requests.ConnectionError as exc:
            if _connection_reason(exc) != _UNRESOLVED or not self._try_mdns_fallback():
                raise self._unreachable(exc)
            try:
                response = self._send(method, path, body, timeout)
            except requests.RequestException as again:
                raise self._unreachable(again)
        except requests.Timeout:
            raise self._unreachable(None, timeout)
        except requests.RequestException as exc:
            raise ClientError("cannot talk to {}: {}".format(self.url, exc), ExitStatus.UNREACHABLE)
        return self._answer(response)

    def close(self):
        """Close the connection pool. Idempotent."""
        self._session.close()

    # internals -----------------------------------------------------------------

    def _send(self, method, path, body, timeout):
        headers = {"Accept": "application/json"}
        if self.token:
            headers["Authorization"] = "Bearer " + self.token
        return self._session.request(
            method, self.url + path, json=body, headers=headers,
            timeout=self.timeout if timeout is None else timeout, allow_redirects=False,
        )

    def _answer(self, response):
        data = _json_of(response)
        if response.ok:
            return data
        if not isinstance(data, dict) or data.get("status") != "error":
            raise ClientError(
                "{} answered HTTP {} but not as a flask-move-server robot does: is --url right?".format(
                    self.url, response.status_code), ExitStatus.ERROR)
        if response.status_code == 401:
            raise ClientError(self._token_advice(data), ExitStatus.UNAUTHORIZED)
        error = ClientError(data.get("message") or data.get("error"), _BY_HTTP_STATUS.get(
            response.status_code, ExitStatus.ERROR))
        error.body = data
        raise error

    def _token_advice(self, data):
        if self.token:
            return ("the robot at {} refused the token: check --token or ROBOT_TOKEN against the robot's "
                    "token (server.token_file in its config).".format(self.url))
        return ("the robot at {} needs a token: pass --token TOKEN or set ROBOT_TOKEN "
                "(the robot's token is in server.token_file of its config).".format(self.url))

    def _unreachable(self, exc, timeout=None):
        if exc is None:
            what = "the robot at {} did not answer within {:g} s".format(
                self.url, self.timeout if timeout is None else timeout)
        else:
            what = "no robot answers at {} ({})".format(self.url, _connection_reason(exc))
        return ClientError(
            what + ". Find robots on this network with 'robotctl discover', then pass --url or set ROBOT_URL.",
            ExitStatus.UNREACHABLE,
        )

    def _try_mdns_fallback(self):
        """``robot.local`` not resolvable by the system: ask mDNS directly, once."""
        parts = urlsplit(self.url)
        host = parts.hostname or ""
        if self._resolved or not host.endswith(".local"):
            return False
        self._resolved = True
        from flask_move_server.lan import discovery

        address = discovery.resolve_local(host, timeout=min(3.0, self.timeout))
        if not address:
            return False
        netloc = ("[{}]".format(address) if ":" in address else address) + (
            ":{}".format(parts.port) if parts.port else "")
        self.url = urlunsplit((parts.scheme, netloc, parts.path, "", "")).rstrip("/")
        return True


def _json_of(response):
    if not response.content:
        return None
    try:
        return response.json()
    except ValueError:
        return {"raw": response.text[:200]}


_UNRESOLVED = "its name does not resolve"


def _causes(exc):
    """``exc`` and everything it wraps (requests → urllib3 → socket), each once."""
    seen, stack = set(), [exc]
    while stack:
        e = stack.pop()
        if e is None or id(e) in seen:
            continue
        seen.add(id(e))
        yield e
        stack += [e.__cause__, e.__context__, getattr(e, "reason", None)]
        stack += [a for a in getattr(e, "args", ()) if isinstance(a, BaseException)]


def _connection_reason(exc):
    # The name did not resolve: a socket.gaierror somewhere in the chain, whatever words
    # urllib3 (2: NameResolutionError, 1.26: NewConnectionError) wraps it in.
    if any(isinstance(e, socket.gaierror) for e in _causes(exc)):
        return _UNRESOLVED
    text = str(exc)
    if "refused" in text.lower():
        return "connection refused"
    if "timed out" in text.lower():
        return "connection timed out"
    return text.split(":")[-1].strip(" )'\"") or "connection failed"


def dumps(data):
    """Pretty JSON for ``--json`` output."""
    return json.dumps(data, indent=2, sort_keys=False, ensure_ascii=False)
