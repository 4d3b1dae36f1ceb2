"""A real third-party VDA 5050 2.0.0 master for the tests: npm's vda-5050-lib (1.4.0, pinned in
tests/vda_master/package-lock.json), its ``MasterController`` run by ``node tests/vda_master/master.js``.

``Master`` starts that process and talks to it in JSON lines: commands on its stdin, events from its
stdout, kept in order by a reader thread. Every event is a dict with an ``"event"`` key:

- ``ready`` {lib, node, pid}: node runs and the library loaded (waited for by ``Master()``).
- ``link`` {state}: the master's own MQTT connection, ``"online"`` / ``"offline"``.
- ``state`` / ``connection`` / ``visualization`` / ``factsheet`` {agv, <the same name>: message}:
  a message from the AGV that the library accepted (its header included).
- ``invalid`` {by, topic, mqttTopic, error, payload}: a message from the AGV that was not accepted.
  ``by: "vda-5050-lib"``: the library dropped it (not JSON, ``version`` not "2.0.0", or its JSON
  schema failed: ``error`` names the first failing keyword, e.g. ``Invalid VDA 5050 State at
  #/allOf/1/required, #/driving``). ``by: "harness"``: the library took it but its payload's
  manufacturer / serialNumber differ from the topic's (the library would then match it to no order).
- order callbacks, each with orderId, orderUpdateId and stateHeaderId (the state that caused it):
  ``nodeTraversed`` {nodeId, sequenceId, nextEdgeId, nextNodeId},
  ``edgeTraversing`` {edgeId, sequenceId, startNodeId, endNodeId, changes, invocation},
  ``edgeTraversed`` {edgeId, sequenceId, startNodeId, endNodeId},
  ``actionStateChanged`` {source: "order", actionId, actionType, actionStatus, resultDescription,
  target: {nodeId | edgeId, sequenceId}, error},
  ``orderProcessed`` {error, byCancelation, active}.
- instant action callbacks: ``actionStateChanged`` {source: "instant", actionId, actionType,
  actionStatus, resultDescription, error, stateHeaderId}, ``actionError`` {source: "instant",
  actionId, actionType, error, stateHeaderId}.
- replies, carrying the command's ``id`` and ``cmd``: ``started`` {lib, vdaVersion, brokerUrl,
  interfaceName, agv, topics, ms}, ``orderAssigned`` {order}, ``orderDiscarded`` {orderId,
  orderUpdateId}, ``instantActionsInitiated`` {instantActions}, ``published`` {topic, mqttTopic,
  payload}, ``stopped``, ``error`` {message} (a reply ``error`` has an ``id``; one without came from
  a callback or the library: ``errors()`` has both).

Example::

    with Master() as master:
        master.start(broker.port, "acme", "robot1")
        sent = master.order({"orderId": "o1", "orderUpdateId": 0, "nodes": [...], "edges": [...]})
        master.wait_event("orderProcessed", orderId="o1", timeout=30)
        assert master.invalid() == []
"""

import collections
import fcntl
import json
import os
import shutil
import subprocess
import threading
import time

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "vda_master")
MASTER_JS = os.path.join(HERE, "master.js")
# Touched after `npm ci` (here and by the Makefile): node_modules matches package-lock.json.
INSTALLED = os.path.join(HERE, "node_modules", ".installed")
NODE_HINT = "Debian bookworm: apt-get install nodejs npm"


class MasterError(AssertionError):
    """The master answered a command with an error, or is gone."""


def ensure_installed():
    """``npm ci`` in tests/vda_master when node_modules is missing or older than the lock file.

    Fails (never skips) when node or npm is missing: the VDA 5050 tests need a real master.
    """
    if shutil.which("node") is None:
        raise RuntimeError("node is not installed: the VDA 5050 tests run vda-5050-lib's master on it ({})"
                           .format(NODE_HINT))
    if _installed():
        return
    npm = shutil.which("npm")
    if npm is None:
        raise RuntimeError("npm is not installed, and tests/vda_master/node_modules is missing or out of date "
                           "({}; or run `make test`)".format(NODE_HINT))
    # One install for pytest-xdist's workers: the second waits for the first, then finds it done.
    with open(os.path.join(HERE, ".install.lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if _installed():
            return
        done = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--loglevel=error"], cwd=HERE,
                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        if done.returncode != 0:
            raise RuntimeError("npm ci in {} failed ({}):\n{}".format(HERE, done.returncode, done.stdout[-3000:]))
        with open(INSTALLED, "w"):
            pass


def _installed():
    try:
        stamp = os.path.getmtime(INSTALLED)
    except OSError:
        return False
    return all(stamp >= os.path.getmtime(os.path.join(HERE, name)) for name in ("package.json", "package-lock.json"))


class Master:
    """vda-5050-lib's MasterController in a node process; see the module's docstring for the events."""

    def __init__(self, timeout=30):
        ensure_installed()
        self._events = []
        self._stderr = collections.deque(maxlen=400)
        self._changed = threading.Condition()
        self._next_id = 0
        self._write_lock = threading.Lock()
        self.proc = subprocess.Popen([shutil.which("node"), MASTER_JS], cwd=HERE, stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                     encoding="utf-8", errors="replace", bufsize=1)
        self._readers = [threading.Thread(target=self._read_events, daemon=True, name="vda-master-out"),
                         threading.Thread(target=self._read_stderr, daemon=True, name="vda-master-err")]
        for reader in self._readers:
            reader.start()
        try:
            self.ready = self.wait_event("ready", timeout=timeout, message="the master's node process to start")
        except BaseException:
            self.close()
            raise

    # -- the process's output ---------------------------------------------------------------------

    def _read_events(self):
        for line in self.proc.stdout:
            line = line.strip()
            if not line:
                continue
            try:
                event = json.loads(line)
            except ValueError:
                event = {"event": "error", "message": "not JSON on the master's stdout: {}".format(line[:500])}
            if not isinstance(event, dict) or "event" not in event:
                event = {"event": "error", "message": "not an event on the master's stdout: {}".format(line[:500])}
            with self._changed:
                self._events.append(event)
                self._changed.notify_all()
        with self._changed:  # EOF: the process is gone (or going); wake whoever waits
            self._changed.notify_all()

    def _read_stderr(self):
        for line in self.proc.stderr:
            self._stderr.append(line.rstrip("\n"))

    def stderr(self):
        """The last lines the master wrote on stderr (the library's own complaints)."""
        return "\n".join(self._stderr)

    # -- events -----------------------------------------------------------------------------------

    def events(self, kind=None):
        """Every event so far (of ``kind`` when given), oldest first."""
        with self._changed:
            return [e for e in self._events if kind is None or e["event"] == kind]

    def last(self, kind):
        """The newest event of ``kind``, or None."""
        seen = self.events(kind)
        return seen[-1] if seen else None

    def mark(self):
        """A position in the events: ``wait_for(..., since=master.mark())`` looks only at newer ones."""
        with self._changed:
            return len(self._events)

    def invalid(self):
        """The AGV's messages that were not accepted (``invalid`` events)."""
        return self.events("invalid")

    def errors(self):
        """``error`` events: failed commands, and whatever went wrong in the library or its callbacks."""
        return self.events("error")

    def assert_clean(self):
        """No invalid message from the AGV, and no error in the master."""
        bad = self.invalid() + self.errors()
        assert not bad, "the master saw:\n" + "\n".join(json.dumps(e) for e in bad)

    def wait_for(self, predicate, timeout=10, message="an event", since=0):
        """The first event from ``since`` on for which ``predicate(event)`` holds; AssertionError after ``timeout``."""
        deadline = time.monotonic() + timeout
        index = since
        with self._changed:
            while True:
                while index < len(self._events):
                    event = self._events[index]
                    index += 1
                    if predicate(event):
                        return event
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                if self.proc.poll() is not None and not self._readers[0].is_alive():
                    raise MasterError("the master exited ({}) while waiting for {}{}".format(
                        self.proc.returncode, message, self._context()))
                self._changed.wait(min(left, 0.5))
        raise AssertionError("timed out after {}s waiting for {}{}".format(timeout, message, self._context()))

    def wait_event(self, kind, timeout=10, message=None, since=0, **fields):
        """The first ``kind`` event from ``since`` on whose ``fields`` have the given values."""
        def matches(event):
            return event["event"] == kind and all(event.get(k) == v for k, v in fields.items())

        what = message or "a {} event{}".format(kind, " with {}".format(fields) if fields else "")
        return self.wait_for(matches, timeout=timeout, message=what, since=since)

    def _context(self):
        with self._changed:
            tail = self._events[-12:]
        text = "\nlast events:\n" + "\n".join("  " + json.dumps(e)[:400] for e in tail)
        if self._stderr:
            text += "\nstderr:\n" + "\n".join(list(self._stderr)[-20:])
        return text

    # -- commands ---------------------------------------------------------------------------------

    def command(self, cmd, timeout=10):
        """Send ``cmd`` (a dict with "cmd") and return its reply event (an ``error`` one included)."""
        with self._write_lock:
            self._next_id += 1
            ident = self._next_id
            line = json.dumps(dict(cmd, id=ident))
            try:
                self.proc.stdin.write(line + "\n")
                self.proc.stdin.flush()
            except (BrokenPipeError, ValueError):
                raise MasterError("the master is gone ({}){}".format(self.proc.poll(), self._context()))
        return self.wait_for(lambda e: e.get("id") == ident, timeout=timeout,
                             message="the master's answer to {}".format(line[:300]))

    def _checked(self, cmd, timeout):
        reply = self.command(cmd, timeout)
        if reply["event"] == "error":
            raise MasterError("{} failed: {}".format(cmd["cmd"], reply["message"]))
        return reply

    def start(self, broker_port, manufacturer, serial, interface_name="uagv", host="127.0.0.1", timeout=20):
        """Connect to the broker and track the AGV ``manufacturer``/``serial``; the ``started`` event.

        Once it returns, the master is subscribed to the AGV's state, connection, visualization and
        factsheet topics (``started["topics"]`` has every topic's full name).
        """
        return self._checked({"cmd": "start", "host": host, "port": broker_port, "interfaceName": interface_name,
                              "manufacturer": manufacturer, "serialNumber": serial}, timeout)

    def order(self, order, timeout=10):
        """``assignOrder`` a headerless order; returns the order as published (with its header).

        The library discards an order whose orderId and orderUpdateId are those of an order it still
        tracks (not yet processed): that raises MasterError here (``raw(..., header=True)`` sends one anyway).
        """
        reply = self._checked({"cmd": "order", "order": order}, timeout)
        if reply["event"] == "orderDiscarded":
            raise MasterError("vda-5050-lib discarded order {orderId}/{orderUpdateId}: it tracks one with these ids"
                              .format(**reply))
        return reply["order"]

    def instant_actions(self, actions, timeout=10):
        """``initiateInstantActions`` with these actions; returns the instantActions message as published."""
        return self._checked({"cmd": "instantActions", "actions": list(actions)}, timeout)["instantActions"]

    def raw(self, topic, payload, header=False, retain=False, timeout=10):
        """Publish on the AGV's ``topic`` past the library's validation: a str as it is, else as JSON.

        ``header=True`` adds the library's header (headerId, timestamp, version, manufacturer,
        serialNumber) first. Returns the ``published`` event (its ``payload`` is the text sent).
        """
        return self._checked({"cmd": "raw", "topic": topic, "payload": payload, "header": header,
                              "retain": retain}, timeout)

    def close(self, timeout=5):
        """Stop the controller and end the process (killed when it does not); always reaped."""
        if self.proc.poll() is None:
            try:
                with self._write_lock:
                    self.proc.stdin.write(json.dumps({"cmd": "stop"}) + "\n")
                    self.proc.stdin.flush()
            except (BrokenPipeError, ValueError, OSError):
                pass
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for reader in self._readers:
            reader.join(2)
        for pipe in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            try:
                pipe.close()
            except (BrokenPipeError, OSError):
                pass

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
