"""Two network namespaces joined by a veth pair: a small LAN for real multicast tests.

``with Lan() as lan:`` creates namespaces ``fmslan<pid>x<random>s`` (the server
side) and ``...c`` (the client side), unique per run, each with ``lo`` up, one end
of the veth pair addressed in 10.<n>.<m>.0/24 and a multicast route
(224.0.0.0/4) on it, then deletes both on exit, also after a failure (deleting a
namespace deletes its veth end, and the pair with it); namespaces of test
processes that were killed outright are swept away by the next run. ``lan.popen(side, argv)``
and ``lan.run(side, argv)`` run commands inside a namespace with
``ip netns exec``. Needs root: :func:`unavailable_reason` says why not.
"""

import os
import random
import re
import subprocess
import uuid

SERVER, CLIENT = "s", "c"
PREFIX = "fmslan"
VETH = {SERVER: "lan-s", CLIENT: "lan-c"}


def _ip(*args, check=True):
    """Run ``ip ARGS``; with ``check``, a failure raises saying the command and ip's stderr."""
    result = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=20)
    if check and result.returncode != 0:
        raise RuntimeError("`ip {}` failed: {}".format(" ".join(args), _said(result)))
    return result


def unavailable_reason():
    """None when namespaces work here; otherwise why the LAN tests cannot run, with ip's own words.

    Creating one is not enough: some containers and chroots let ``ip netns add`` succeed and then
    refuse ``ip -n`` (no sysfs to mount in the namespace) or ``ip netns exec``; each is tried once.
    """
    probe = "fmsprobe{}".format(uuid.uuid4().hex[:8])
    try:
        result = _ip("netns", "add", probe, check=False)
    except (OSError, subprocess.SubprocessError) as exc:
        return "`ip netns` is not available ({}): real-multicast mDNS tests need iproute2 and root".format(exc)
    if result.returncode != 0:
        return "`ip netns add` failed ({}): real-multicast mDNS tests need root (CI has it)".format(_said(result))
    try:
        return _use_reason(probe)
    finally:
        _ip("netns", "del", probe, check=False)


def _use_reason(namespace):
    """Why the namespace just made cannot be configured or run in (``ip -n``, ``ip netns exec``), or None."""
    for what, argv in (("ip -n", ["-n", namespace, "link", "set", "lo", "up"]),
                       ("ip netns exec", ["netns", "exec", namespace, "true"])):
        try:
            result = _ip(*argv, check=False)
        except (OSError, subprocess.SubprocessError) as exc:
            return "`{}` failed ({}): real-multicast mDNS tests need working network namespaces".format(what, exc)
        if result.returncode != 0:
            return "`{}` failed ({}): real-multicast mDNS tests need working network namespaces".format(
                what, _said(result))
    return None


def _said(result):
    """What a failed ``ip`` said: its stderr, else its exit status."""
    return result.stderr.strip() or "exit {}".format(result.returncode)


def sweep_stale():
    """Delete namespaces left by test processes that died without cleaning up (SIGKILL)."""
    listing = _ip("netns", "list", check=False).stdout
    for name in re.findall(r"^({}(\d+)x[0-9a-f]+[sc])\b".format(PREFIX), listing, re.M):
        if not os.path.exists("/proc/{}".format(name[1])):
            _ip("netns", "del", name[0], check=False)


class Lan:
    """Two namespaces and a veth pair between them; closed (deleted) exactly once."""

    def __init__(self):
        tag = "{}{}x{}".format(PREFIX, os.getpid(), uuid.uuid4().hex[:6])
        self.names = {SERVER: tag + "s", CLIENT: tag + "c"}
        subnet = "10.{}.{}".format(random.randint(100, 250), random.randint(0, 250))
        self.subnet = subnet
        self.addresses = {SERVER: subnet + ".1", CLIENT: subnet + ".2"}
        self._created = []

    def __enter__(self):
        sweep_stale()
        try:
            self.create()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc):
        self.close()

    def create(self):
        for side in (SERVER, CLIENT):
            _ip("netns", "add", self.names[side])
            self._created.append(self.names[side])
        _ip("link", "add", VETH[SERVER], "netns", self.names[SERVER], "type", "veth",
            "peer", "name", VETH[CLIENT], "netns", self.names[CLIENT])
        for side in (SERVER, CLIENT):
            self.ip(side, "link", "set", "lo", "up")
            self.ip(side, "addr", "add", self.addresses[side] + "/24", "dev", VETH[side])
            self.ip(side, "link", "set", VETH[side], "up")
            self.ip(side, "route", "add", "224.0.0.0/4", "dev", VETH[side])

    def ip(self, side, *args):
        """Run ``ip ARGS`` inside one side's namespace (raises on failure)."""
        return _ip("-n", self.names[side], *args)

    def change_address(self, side, new_address):
        """Replace the side's address on its veth end, as a DHCP client does on a new lease.

        Removing the last address flushes the device's routes, so the multicast
        route is put back, as a DHCP client restores the default route.
        """
        old = self.addresses[side]
        self.ip(side, "addr", "del", old + "/24", "dev", VETH[side])
        self.ip(side, "addr", "add", new_address + "/24", "dev", VETH[side])
        self.ip(side, "route", "replace", "224.0.0.0/4", "dev", VETH[side])
        self.addresses[side] = new_address

    def command(self, side, argv):
        """``argv`` prefixed to run inside the side's namespace."""
        return ["ip", "netns", "exec", self.names[side], *argv]

    def popen(self, side, argv, **kw):
        """Start ``argv`` inside the side's namespace; returns the Popen."""
        return subprocess.Popen(self.command(side, argv), **kw)

    def run(self, side, argv, timeout=30, **kw):
        """Run ``argv`` inside the side's namespace to completion; returns CompletedProcess."""
        return subprocess.run(self.command(side, argv), timeout=timeout, **kw)

    def close(self):
        """Delete both namespaces (and the veth pair with them). Idempotent."""
        while self._created:
            _ip("netns", "del", self._created.pop(), check=False)
