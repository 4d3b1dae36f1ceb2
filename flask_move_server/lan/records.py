"""What the robot says on the LAN over mDNS, and how a clash with another device shows. Pure.

:func:`service_records` builds the two services (``_http._tcp`` and ``_flask-move._tcp``, one
instance name, TXT ``path``, ``api``, ``token``, ``version``) and :func:`reachable_addresses`
the host name's A/AAAA addresses from the interfaces a bound server is reachable on;
:func:`conflict_questions` and :func:`conflicts` ask and judge whether another device already
answers for the host or instance name. :mod:`flask_move_server.lan.mdns` puts them on the air.
"""

import collections
import ipaddress

from flask_move_server import API_VERSION, __version__
from flask_move_server.lan import dns_wire
from flask_move_server.lan.discovery import OWN_SERVICE_TYPE

HTTP_SERVICE_TYPE = "_http._tcp.local."
SERVICE_TYPES = (OWN_SERVICE_TYPE, HTTP_SERVICE_TYPE)
WILDCARD_V4 = ("0.0.0.0", "")
WILDCARD_ANY = ("::", "*")

ServiceRecord = collections.namedtuple("ServiceRecord", "type name server port properties addresses")
ServiceRecord.__doc__ = "One service to register: what zeroconf's ServiceInfo is built from."


def txt_properties(token_required, api_version=API_VERSION, version=__version__):
    """The TXT record: where the API lives, its version, whether a token is needed."""
    return {"path": "/", "api": str(api_version), "token": "yes" if token_required else "no", "version": version}


def service_records(instance, hostname, port, addresses, token_required):
    """The services to register for ``instance`` served on ``hostname``:``port``.

    ``addresses`` are the A/AAAA records attached to the host name; pass none
    when another responder (avahi) owns the host name.
    """
    server = hostname.rstrip(".")
    if not server.endswith(".local"):
        server += ".local"
    properties = txt_properties(token_required)
    return [
        ServiceRecord(type_, "{}.{}".format(instance, type_), server + ".", port, dict(properties), tuple(addresses))
        for type_ in SERVICE_TYPES
    ]


def reachable_addresses(bind_host, interface_addresses):
    """The addresses a server bound to ``bind_host`` is reachable on, sorted.

    ``interface_addresses``: (interface name, address) pairs of this machine.
    ``0.0.0.0`` reaches every IPv4 address, ``::``/``*`` every IPv4 and IPv6
    address, a specific address only itself (when the machine has it).
    Loopback and IPv6 link-local addresses are never advertised.
    """
    found = set()
    for _ifname, text in interface_addresses:
        try:
            addr = ipaddress.ip_address(text.split("%")[0])
        except ValueError:
            continue
        if addr.is_loopback or (addr.version == 6 and addr.is_link_local):
            continue
        if bind_host in WILDCARD_V4 and addr.version != 4:
            continue
        if bind_host not in WILDCARD_V4 + WILDCARD_ANY and not _same_address(bind_host, addr):
            continue
        found.add(addr)
    return tuple(str(a) for a in sorted(found, key=lambda a: (a.version, a)))


def _same_address(host, addr):
    try:
        return ipaddress.ip_address(host) == addr
    except ValueError:
        return False


def conflict_questions(hostname, instance):
    """The questions whose answers reveal a clash: the host's A record, the instances' SRV records."""
    questions = [("{}.{}".format(instance, type_), dns_wire.TYPE_SRV) for type_ in SERVICE_TYPES]
    if hostname is not None:
        questions.append((hostname + ".local.", dns_wire.TYPE_A))
    return questions


def conflicts(records, hostname, instance, our_addresses):
    """(addresses of other devices answering for ``hostname``.local, whether ``instance`` is taken)."""
    others = [a for a in dns_wire.addresses_of(records, hostname + ".local.") if a not in our_addresses]
    names = {"{}.{}".format(instance, type_).lower() for type_ in SERVICE_TYPES}
    taken = any(rtype == dns_wire.TYPE_SRV and rname.lower() in names for rname, rtype, _ in records)
    return others, taken


def numbered(name, number):
    """``robot`` -> ``robot-2``: the name to try after a conflict."""
    return "{}-{}".format(name, number)
