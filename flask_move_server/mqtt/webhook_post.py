"""One webhook POST in bounded time and memory, and the signature that tells a receiver it is the robot's.

requests bounded each socket read, not the try, and read the answer whole: a receiver trickling a
byte every 3 s held the webhooks' worker indefinitely, and one answering an endless body took the
robot's memory to 3 GB (issue 34). Here a try is connect, send, the status line and headers, all
within ``timeout`` s: a timer shuts the socket down when it runs over. The answer's body is never
read (only its status counts); its headers are bounded by http.client (100 lines of at most 64 KB).
The standard library reads no proxy from the environment and no ``~/.netrc``. Pure: no ROS.
"""

import hashlib
import hmac
import http.client
import socket
import ssl
import threading
from urllib.parse import quote, urlsplit

SIGNATURE_HEADER = "X-Robot-Signature-256"


class RanOver(Exception):
    """The try took longer than its time: connect, send and the answer's status line and headers."""


def signature(secret, data):
    """``sha256=<hex>``: the HMAC-SHA256 of the body ``data`` (bytes) with ``secret`` (bytes), as GitHub signs."""
    return "sha256=" + hmac.new(secret, data, hashlib.sha256).hexdigest()


def post(url, data, headers, timeout):
    """POST ``data`` (bytes) to ``url``: the answer's HTTP status. RanOver after ``timeout`` s in all; OSError or
    http.client.HTTPException when it failed otherwise. Redirects are not followed (the status says so)."""
    parts = urlsplit(url)
    if parts.scheme.lower() == "https":
        connection = http.client.HTTPSConnection(parts.hostname, parts.port, timeout=timeout,
                                                 context=ssl.create_default_context())
    else:
        connection = http.client.HTTPConnection(parts.hostname, parts.port, timeout=timeout)
    ran_over = threading.Event()
    cutter = threading.Timer(timeout, _cut, (connection, ran_over))
    cutter.daemon = True
    cutter.start()
    try:
        connection.request("POST", _target(parts), body=data, headers=headers)
        return connection.getresponse().status  # the status line and headers; the body is left unread
    except (OSError, http.client.HTTPException, ValueError):
        if ran_over.is_set():
            raise RanOver("no answer within {:g} s".format(timeout)) from None
        raise
    finally:
        cutter.cancel()
        connection.close()


def _cut(connection, ran_over):
    """The try ran over: its socket is shut down, so the read or write it is blocked in returns."""
    ran_over.set()
    sock = connection.sock
    if sock is not None:
        try:
            sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass  # closed meanwhile


def _target(parts):
    """The request target of a URL's parts: its path (``/`` when none) and query, percent-encoded where needed."""
    target = (parts.path or "/") + ("?" + parts.query if parts.query else "")
    return quote(target, safe="/%?=&:@!$'()*+,;~")
