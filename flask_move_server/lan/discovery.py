"""Find robots on the LAN, and resolve ``NAME.local`` where the system cannot.

The client side of :mod:`flask_move_server.lan.mdns`. API (used by ``robotctl``):

``discover(timeout=3.0) -> list of FoundRobot``
    Browse ``_flask-move._tcp.local.`` for ``timeout`` seconds and return every
    robot that answered, sorted by name: ``FoundRobot(name, host, addresses, port,
    token_required, version, api_version)``; ``robot.url`` is its base URL
    (``http://robot.local:5000``). Returns ``[]`` when none answers.

``resolve_local(hostname, timeout=2.0) -> address or None``
    Ask the LAN over mDNS for ``hostname`` (``robot.local``) and return the first
    address that answers (IPv4 preferred), or None. For machines whose system
    resolver knows nothing of ``.local`` (no nss-mdns: minimal Linux, Android,
    Windows without Bonjour). Other names return None without a query.

``query_addresses(hostname, timeout) -> list of str``
    Every address that answered for ``hostname`` within ``timeout``.

``ask(questions, timeout) -> list of (name, type, rdata)``
    The raw records answered to (name, type) questions (the advertiser's
    conflict checks use it).

The queries are one-shot ("legacy unicast", RFC 6762 section 6.7): sent from an
ephemeral port to 224.0.0.251:5353 on every IPv4 interface, answered straight
back by any responder (python-zeroconf, avahi, Bonjour). The packet codec is
:mod:`flask_move_server.lan.dns_wire` (pure); this module holds the sockets and the
browsing.
"""

import collections
import random
import select
import socket
import time

from flask_move_server.lan.dns_wire import TYPE_A, TYPE_AAAA, addresses_of, build_query, local_name, parse_records

OWN_SERVICE_TYPE = "_flask-move._tcp.local."
MDNS_GROUP = "224.0.0.251"
MDNS_PORT = 5353
QUERY_RESEND = 1.0


class FoundRobot(collections.namedtuple("FoundRobot", "name host addresses port token_required version api_version")):
    """One robot found on the LAN (what its mDNS service record says; not the Robot facade)."""

    __slots__ = ()

    @property
    def url(self):
        """The API's base URL, by host name (``http://robot.local:5000``)."""
        return "http://{}:{}".format(self.host, self.port)


# ---- asking the network -----------------------------------------------------


def interface_addresses():
    """(interface name, address) for every address of this machine, from ifaddr."""
    import ifaddr

    pairs = []
    for adapter in ifaddr.get_adapters():
        for ip in adapter.ips:
            address = ip.ip if isinstance(ip.ip, str) else ip.ip[0]
            pairs.append((adapter.nice_name, address))
    return pairs


def resolve_local(hostname, timeout=2.0):
    """The first address answering for ``hostname`` over mDNS (IPv4 preferred), or None."""
    addresses = query_addresses(hostname, timeout, first=True)
    v4 = [a for a in addresses if ":" not in a]
    return (v4 or addresses or [None])[0]


def query_addresses(hostname, timeout=2.0, first=False):
    """Every address answering for ``hostname`` within ``timeout`` (``first``: stop at the first)."""
    name = local_name(hostname)
    if name is None:
        return []
    return addresses_of(ask([(name, TYPE_A), (name, TYPE_AAAA)], timeout, first), name)


def ask(questions, timeout, first=False):
    """Records answered to ``questions`` ((name, type) pairs) within ``timeout`` seconds.

    ``first``: return as soon as one answer arrives. Resent every second.
    """
    query_id = random.randint(1, 0xFFFF)
    packet = build_query(questions, query_id)
    sockets = _query_sockets()
    records = []
    try:
        deadline = time.monotonic() + timeout
        next_send = 0.0
        while time.monotonic() < deadline and not (first and records):
            now = time.monotonic()
            if now >= next_send:
                _send_all(sockets, packet)
                next_send = now + QUERY_RESEND
            ready, _, _ = select.select(sockets, [], [], max(0.0, min(deadline, next_send) - now))
            for sock in ready:
                records.extend(_receive(sock, query_id))
    finally:
        for sock in sockets:
            sock.close()
    return records


def _query_sockets():
    """One UDP socket per non-loopback IPv4 interface, plus one on the default route."""
    sources = [None]
    try:
        sources += sorted({a for _n, a in interface_addresses() if ":" not in a and not a.startswith("127.")})
    except OSError:
        pass
    sockets = []
    for source in sources:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 255)
        if source:
            sock.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(source))
        sockets.append(sock)
    return sockets


def _send_all(sockets, packet):
    for sock in sockets:
        try:
            sock.sendto(packet, (MDNS_GROUP, MDNS_PORT))
        except OSError:
            pass  # an interface without a multicast route, or gone since listed


def _receive(sock, query_id):
    try:
        data, _source = sock.recvfrom(9000)
    except OSError:
        return []
    return parse_records(data, query_id)


# ---- browsing ---------------------------------------------------------------


def discover(timeout=3.0, service_type=OWN_SERVICE_TYPE):
    """Every robot advertising ``service_type`` on the LAN, sorted by name."""
    from zeroconf import ServiceBrowser, Zeroconf

    deadline = time.monotonic() + timeout
    zc = Zeroconf()
    try:
        names = set()
        browser = ServiceBrowser(zc, service_type, handlers=[_collector(names)])
        time.sleep(max(0.0, timeout * 0.6))
        browser.cancel()
        robots = []
        for name in sorted(names):
            remaining_ms = int(max(0.1, deadline - time.monotonic()) * 1000)
            info = zc.get_service_info(service_type, name, timeout=remaining_ms)
            if info is not None and info.port:
                robots.append(robot_from_service(service_type, name, info))
        return robots
    finally:
        zc.close()


def _collector(names):
    from zeroconf import ServiceStateChange

    def on_change(zeroconf, service_type, name, state_change):
        if state_change is ServiceStateChange.Removed:
            names.discard(name)
        else:
            names.add(name)

    return on_change


def robot_from_service(service_type, name, info):
    """A :class:`FoundRobot` from a resolved zeroconf ServiceInfo."""
    props = {_text(k): _text(v) for k, v in info.properties.items()}
    instance = name[: -len(service_type) - 1] if name.endswith("." + service_type) else name
    return FoundRobot(
        name=instance,
        host=(info.server or "").rstrip("."),
        addresses=tuple(info.parsed_addresses()),
        port=info.port,
        token_required=props.get("token") == "yes",
        version=props.get("version"),
        api_version=props.get("api"),
    )


def _text(value):
    if isinstance(value, bytes):
        return value.decode("utf-8", "replace")
    return value
