"""Refuse what a web page the operator visits could send: cross-site requests and DNS rebinding.

A robot without a token (127.0.0.1, ``make demo``, ``--insecure`` on a LAN) obeys whoever reaches
it, and the operator's browser does: any page it shows can POST ``text/plain`` JSON to
``http://127.0.0.1:5000/goto`` (no CORS preflight for that), or point a name of its own at the
robot's address (DNS rebinding) and then read and write the API as if it were the same site.
Two checks, before the token check so they protect token-less robots too:

- ``Host`` must be a name of this robot (see :class:`HostNames`) or an IP address; rebinding
  needs a name of the attacker's, and ``server.allowed_hosts`` adds the robot's other names.
- ``Origin``, when a browser sends it (every cross-origin fetch and form post does), must be the
  robot itself; ``Origin: null`` (sandboxed pages, local files) and ``Sec-Fetch-Site:
  cross-site`` (except following a link to the page) are refused. curl, robotctl and requests
  send no Origin and are not affected.
"""

import functools
import ipaddress
import json
import re
import socket
from urllib.parse import urlsplit

from flask import request

from flask_move_server.core.errors import ForbiddenOrigin, UnknownHost

ANY_HOST = "*"


class HostNames:
    """The names this robot answers to in a request's ``Host`` header (the port is ignored).

    IP addresses, ``localhost``, ``server.host``, ``<mdns.hostname>.local`` with its conflict
    variants (``robot-2.local``), the machine's host name with and without ``.local``, and
    ``server.allowed_hosts`` (exact names, ``.example.org`` for a domain and its subdomains,
    ``*`` for any name).
    """

    def __init__(self, config, machine_name=None):
        machine = (machine_name or socket.gethostname()).lower().rstrip(".")
        short = machine.split(".")[0]
        self.names = {"localhost", config.server.host.lower(), machine, short, short + ".local"}
        extra = [h.lower().rstrip(".") for h in config.server.allowed_hosts]
        self.names.update(h for h in extra if not h.startswith("."))
        self.domains = tuple(h for h in extra if h.startswith("."))
        self.any = ANY_HOST in config.server.allowed_hosts
        self._mdns = re.compile(r"{}(-[0-9]+)?\.local".format(re.escape(config.mdns.hostname.lower())))

    def allows(self, host):
        """True when ``host`` (a Host header: name or address, maybe a port) names this robot."""
        name = host_name(host)
        if self.any or name in self.names or _is_address(name) or self._mdns.fullmatch(name):
            return True
        return any(name.endswith(d) or name == d[1:] for d in self.domains)


def host_name(host):
    """``Host`` without its port, lower case, without a final dot: ``[::1]:5000`` -> ``::1``."""
    host = host.strip().lower()
    if host.startswith("["):
        return host[1:].partition("]")[0]
    if host.count(":") == 1:
        host = host.partition(":")[0]
    return host.rstrip(".")


def _is_address(name):
    try:
        ipaddress.ip_address(name.partition("%")[0])  # fe80::1%eth0: a link-local address and its zone
    except ValueError:
        return False
    return True


def init_app(app, config):
    """Check every request's Host and Origin before anything else runs."""
    names = HostNames(config)

    allows = functools.lru_cache(maxsize=64)(names.allows)  # a robot is called by a few names, before every request

    @app.before_request
    def _check_where_from():
        environ = request.environ  # read once: this runs before every request, /goto's too
        host = environ.get("HTTP_HOST")
        if host is not None and not allows(host):
            raise UnknownHost(
                "This robot does not know the name {} it was called by (the Host header), so the request is "
                "refused: a web page can give its own name the robot's address. If the robot has that name on "
                "your network, add it to server.allowed_hosts in its config.".format(_shown(host_name(host))))
        problem = cross_site(environ, environ.get("REQUEST_METHOD", "GET").upper())
        if problem:
            raise ForbiddenOrigin(
                "Requests from other web pages are refused ({}), so a page you visit cannot drive the robot. "
                "Use the robot's own page, robotctl or curl.".format(problem))
        return None


def cross_site(environ, method="GET"):
    """Why a request with this WSGI ``environ`` comes from another site's page (a short phrase), or None."""
    origin = environ.get("HTTP_ORIGIN")
    if origin is not None and not _same_origin(origin, environ.get("HTTP_HOST")):
        return "Origin: {}{}".format(_shown(origin), ", a sandboxed page or a file" if origin == "null" else "")
    fetch_site = environ.get("HTTP_SEC_FETCH_SITE", "").lower()
    navigating = environ.get("HTTP_SEC_FETCH_MODE", "").lower() == "navigate" and method in ("GET", "HEAD")
    if fetch_site == "cross-site" and not navigating:  # following a link to the page is fine; a form post is not
        return "Sec-Fetch-Site: cross-site"
    return None


def _same_origin(origin, host):
    """True when ``origin`` is ``http(s)://<host>``: the page making the request is the robot's own."""
    try:
        parts = urlsplit(origin.strip())
    except ValueError:  # e.g. "http://[" : no origin a browser sends
        return False
    return parts.scheme in ("http", "https") and host is not None and parts.netloc.lower() == host.strip().lower()


def _shown(text):
    return json.dumps(text[:100])
