"""Advertise the robot on the LAN over mDNS (python-zeroconf).

What goes on the wire (built by the pure :mod:`flask_move_server.lan.records`):

- the API as ``_http._tcp.local.`` (generic browsers and phone apps see it) and
  as ``_flask-move._tcp.local.`` (what ``robotctl discover`` looks for), both
  under one instance name (default: the host name), with TXT ``path=/``,
  ``api=<API_VERSION>``, ``token=yes|no`` and ``version=<package version>``;
- the host name (default ``robot`` -> ``robot.local.``) with an A (AAAA) record
  for every non-loopback address the HTTP server is reachable on. python-zeroconf
  has no API for a bare host record: the services' SRV target (``server=``)
  carries the addresses, and zeroconf then answers A/AAAA queries for it.

When avahi-daemon runs on the machine it owns the host name (two responders for
one name make avahi rename the host), so only the services are registered, with
avahi's host name as their target. An instance-name clash is resolved by
zeroconf (``robot-2``) and logged; a host-name clash (another device answering
for ``robot.local``) is detected by a query before claiming the name, reported
with the fix, and this robot answers as ``robot-2.local`` meanwhile.

The :class:`Advertiser` owns one thread that polls the interfaces (ifaddr) every
``address_check_period`` seconds and re-registers when the reachable addresses
change (DHCP renewal, Wi-Fi reconnect). It re-creates the Zeroconf instance then,
because zeroconf's per-interface sockets keep the old source address.
``close()`` withdraws every record (goodbye packets) and is idempotent.
"""

import collections
import logging
import os
import socket
import threading

from flask_move_server.lan import discovery
from flask_move_server.lan.discovery import OWN_SERVICE_TYPE, interface_addresses
from flask_move_server.lan.records import (
    WILDCARD_ANY,
    WILDCARD_V4,
    conflict_questions,
    conflicts,
    numbered,
    reachable_addresses,
    service_records,
)

log = logging.getLogger(__name__)

AVAHI_PID_FILE = "/run/avahi-daemon/pid"
CONFLICT_QUERY_TIME = 1.0

Published = collections.namedtuple("Published", "hostname instances addresses port")
Published.__doc__ = "What is on the air now: host name, instance names by service type, addresses."


def avahi_running(pid_file=AVAHI_PID_FILE):
    """True when avahi-daemon runs on this machine (its pid file names a live process)."""
    try:
        with open(pid_file, encoding="ascii") as f:
            pid = int(f.read().strip())
    except (OSError, ValueError):
        return False
    try:
        os.kill(pid, 0)
    except PermissionError:
        return True
    except OSError:
        return False
    return True


class Advertiser:
    """Keeps the robot's mDNS records on the air while the server runs."""

    def __init__(self, settings, bind_host, port, token_required, avahi_pid_file=AVAHI_PID_FILE):
        self.settings = settings
        self.bind_host = bind_host
        self.port = port
        self.token_required = token_required
        self._avahi_pid_file = avahi_pid_file
        self._stop = threading.Event()
        self._changed = threading.Condition()
        self._lock = threading.Lock()
        self._thread = None
        self._zeroconf = None
        self._addresses = None
        self.published = None

    def start(self):
        """Start advertising in the background (registration takes a second or two)."""
        if self._thread is None and not self._stop.is_set():
            self._thread = threading.Thread(target=self._run, name="mdns-advertiser", daemon=True)
            self._thread.start()
        return self

    def wait_published(self, timeout):
        """Block until records are on the air; returns :class:`Published` or None."""
        with self._changed:
            self._changed.wait_for(lambda: self.published is not None, timeout)
            return self.published

    def close(self):
        """Withdraw every record (goodbye packets) and stop. Idempotent."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(15)
        self._withdraw()

    def _run(self):
        try:
            while not self._stop.is_set():
                self._refresh()
                self._stop.wait(self.settings.address_check_period)
        finally:
            self._withdraw()

    def _refresh(self):
        try:
            addresses = reachable_addresses(self.bind_host, interface_addresses())
        except OSError as exc:
            log.warning("mDNS: cannot list network interfaces: %s", exc)
            return
        if addresses == self._addresses:
            return
        if self._addresses is not None:
            log.info("mDNS: addresses changed from %s to %s: advertising again",
                     ", ".join(self._addresses) or "none", ", ".join(addresses) or "none")
        self._withdraw()
        if not addresses:
            log.warning("mDNS: no network address reaches %s yet: not advertising until one appears",
                        self.bind_host)
            self._addresses = addresses
            return
        try:
            self._publish(addresses)
            self._addresses = addresses
        except Exception as exc:  # the network may vanish mid-registration: retry next period
            log.warning("mDNS: advertising failed (%s: %s); retrying in %.0f s",
                        type(exc).__name__, exc, self.settings.address_check_period)
            self._withdraw()

    def _publish(self, addresses):
        from zeroconf import Zeroconf

        hostname, instance, claim = self._names(addresses)
        self._zeroconf = zc = Zeroconf(**zeroconf_arguments(self.bind_host, addresses))
        records = service_records(instance, hostname, self.port, addresses if claim else (), self.token_required)
        instances = {}
        for record in records:
            if self._stop.is_set():
                return
            info = _service_info(record)
            zc.register_service(info, allow_name_change=True)
            if info.name != record.name:
                log.warning("mDNS: another device already advertises %r; this robot is %r instead. "
                            "Set mdns.instance in the config to a unique name.", record.name, info.name)
            instances[record.type] = info.name
        self._set_published(Published(hostname + ".local", instances, addresses if claim else (), self.port))
        log.info("mDNS: advertising %s on http://%s.local:%d/ (%s)",
                 instances[OWN_SERVICE_TYPE], hostname, self.port, ", ".join(addresses))

    def _names(self, addresses):
        """(host name, instance name, whether this process answers for the host name)."""
        wanted = self.settings.publish_hostname
        claim = not (wanted == "never" or (wanted == "auto" and avahi_running(self._avahi_pid_file)))
        hostname = self.settings.hostname
        if not claim:
            hostname = socket.gethostname().split(".")[0]
            if wanted == "auto" and hostname != self.settings.hostname:
                log.warning("mDNS: avahi-daemon owns the host name, so the robot answers as %s.local, "
                            "not %s.local. To use %s.local: sudo hostnamectl set-hostname %s",
                            hostname, self.settings.hostname, self.settings.hostname, self.settings.hostname)
        instance = self.settings.instance or hostname
        return self._free_names(hostname, instance, addresses if claim else None) + (claim,)

    def _free_names(self, hostname, instance, addresses):
        """Names nobody else answers for: ``robot-2`` after ``robot``, and so on, logged.

        ``addresses`` None: the host name is not ours to check (avahi owns it).
        The check is a one-shot query, answered straight to our own socket.
        """
        host, name = hostname, instance
        for number in range(2, 10):
            if self._stop.is_set():
                break
            records = discovery.ask(conflict_questions(host if addresses is not None else None, name),
                                    CONFLICT_QUERY_TIME)
            other_hosts, name_taken = conflicts(records, host, name, addresses or ())
            if addresses is not None and other_hosts:
                log.error("mDNS: host name conflict: %s.local is already used by another device at %s. "
                          "Fix: give this robot a unique name (mdns.hostname in the config) or rename the "
                          "other device. Until then this robot answers as %s.local.",
                          host, ", ".join(other_hosts), numbered(hostname, number))
                host = numbered(hostname, number)
            if name_taken:
                log.warning("mDNS: another device already advertises the name %r; this robot is %r instead. "
                            "Set mdns.instance in the config to a unique name.", name, numbered(instance, number))
                name = numbered(instance, number)
            if not (name_taken or (addresses is not None and other_hosts)):
                break
        return host, name

    def _set_published(self, published):
        with self._changed:
            self.published = published
            self._changed.notify_all()

    def _withdraw(self):
        with self._lock:
            zc, self._zeroconf = self._zeroconf, None
            self._addresses = None
        self._set_published(None)
        if zc is None:
            return
        try:
            zc.unregister_all_services()
        finally:
            zc.close()


def zeroconf_arguments(bind_host, addresses):
    """Which interfaces and IP versions zeroconf listens and answers on."""
    from zeroconf import InterfaceChoice, IPVersion

    if bind_host in WILDCARD_V4:
        return {"interfaces": InterfaceChoice.All, "ip_version": IPVersion.V4Only}
    if bind_host in WILDCARD_ANY:
        return {"interfaces": InterfaceChoice.All, "ip_version": IPVersion.All}
    version = IPVersion.V6Only if ":" in bind_host else IPVersion.V4Only
    return {"interfaces": list(addresses), "ip_version": version}


def _service_info(record):
    from zeroconf import ServiceInfo

    return ServiceInfo(
        record.type,
        record.name,
        port=record.port,
        properties=record.properties,
        server=record.server,
        parsed_addresses=list(record.addresses),
    )
