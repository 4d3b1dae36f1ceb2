"""A Server-Sent Events reader for tests and benchmarks: ``GET /events`` as the page reads it.

requests with ``stream=True`` hands over each HTTP chunk as it arrives (``iter_content(None)``),
so an event is seen when the server sends it, not when a buffer fills.
"""

import json
import time

import requests


class EventReader:
    """One open ``/events`` stream: ``next()`` gives ``(kind, data)``, comments kept in ``comments``."""

    def __init__(self, url, headers=None, timeout=10, kinds=None):
        self.kinds = kinds  # None: every kind; else the others are skipped (the test's concern only)
        self.response = requests.get(url + "/events", headers=headers, stream=True, timeout=timeout)
        self.status_code = self.response.status_code
        self.comments = []
        self.retry = None
        self.ended = False  # the server ended the stream cleanly (the last chunk came)
        self._chunks = self.response.iter_content(None) if self.status_code == 200 else iter(())
        self._buffer = ""

    def next(self, comments=False):
        """The next event ``(kind, data)`` (with ``comments``, also ``(":", text)``); None once ended."""
        while True:
            block, sep, rest = self._buffer.partition("\n\n")
            if sep:
                self._buffer = rest
                event = self._parse(block)
                if event is not None and self.kinds is not None and event[0] not in self.kinds:
                    continue
                if event is not None:
                    return event
                if comments and block.startswith(":"):
                    return ":", block[1:].strip()
                continue
            chunk = next(self._chunks, None)
            if chunk is None:
                self.ended = True
                return None
            self._buffer += chunk.decode("utf-8")

    def until(self, predicate, timeout=30):
        """Read events until ``predicate(kind, data)``; that event, or AssertionError after ``timeout`` s."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            event = self.next()
            assert event is not None, "the stream ended before the event awaited"
            if predicate(*event):
                return event
        raise AssertionError("no such event within {} s".format(timeout))

    def _parse(self, block):
        kind, data = "message", []
        for line in block.split("\n"):
            if line.startswith(":"):
                self.comments.append(line[1:].strip())
            elif line.startswith("retry:"):
                self.retry = int(line[6:])
            elif line.startswith("event:"):
                kind = line[6:].strip()
            elif line.startswith("data:"):
                data.append(line[5:].strip())
        return (kind, json.loads("\n".join(data))) if data else None

    def close(self):
        self.response.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def received_at(reader, predicate):
    """Read until ``predicate``; (the event, time.monotonic() when it was read)."""
    event = reader.until(predicate)
    return event, time.monotonic()


class EventLog(EventReader):
    """An ``/events`` stream read all along by a thread of its own, its events kept (``events``): for a test
    that waits for something else meanwhile. A reader left unread takes nothing, and the server disconnects
    one that takes nothing for ``server.channel_timeout`` (30 s), as it does a phone out of Wi-Fi range."""

    def __init__(self, url, headers=None, timeout=10, kinds=None):
        import threading

        super().__init__(url, headers=headers, timeout=timeout, kinds=kinds)
        self.events = []
        self._thread = threading.Thread(target=self._read_all, name="event-log", daemon=True)
        self._thread.start()

    def _read_all(self):
        try:
            while True:
                event = self.next()
                if event is None:
                    return
                self.events.append(event)
        except Exception:  # closed under the reader, or timed out: the events so far stand
            self.ended = True

    def until(self, predicate, timeout=30):
        """The first event kept so far or within ``timeout`` s that ``predicate(kind, data)`` holds for."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for event in list(self.events):
                if predicate(*event):
                    return event
            time.sleep(0.05)
        raise AssertionError("no such event within {} s".format(timeout))
