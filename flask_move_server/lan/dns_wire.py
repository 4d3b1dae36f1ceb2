"""The DNS wire format, as much of it as one-shot mDNS queries need (RFC 1035, RFC 6762).

Pure and tiny on purpose: builds a query packet, reads the records of a response (following
compression pointers, refusing pointer loops), picks the A/AAAA addresses of a name. It needs
no zeroconf internals, which change between zeroconf 0.47 and the newest release; a malformed
packet yields no records, never an exception. Used by :mod:`flask_move_server.lan.discovery` to ask
and by :mod:`flask_move_server.lan.mdns` for its conflict checks.
"""

import ipaddress
import struct

TYPE_A, TYPE_SRV, TYPE_AAAA, CLASS_IN = 1, 33, 28, 1


def local_name(hostname):
    """``robot.local`` / ``robot.local.`` -> ``robot.local.``; None for other names."""
    name = hostname.strip().rstrip(".").lower()
    if not name.endswith(".local") or name == ".local":
        return None
    return name + "."


def build_query(questions, query_id):
    """A DNS query packet asking each (name, type) of ``questions``."""
    packet = struct.pack("!HHHHHH", query_id, 0, len(questions), 0, 0, 0)
    for name, type_ in questions:
        packet += encode_name(name) + struct.pack("!HH", type_, CLASS_IN)
    return packet


def encode_name(name):
    """``robot.local.`` in DNS wire form (length-prefixed labels, no compression)."""
    labels = [label.encode("utf-8") for label in name.rstrip(".").split(".")]
    if any(not 0 < len(label) < 64 for label in labels):
        raise ValueError("not a valid DNS name: {!r}".format(name))
    return b"".join(struct.pack("!B", len(label)) + label for label in labels) + b"\0"


def parse_records(packet, query_id=None):
    """(name, type, rdata bytes) of every record in a DNS response (answers and additionals)."""
    try:
        qid, flags, qd, an, ns, ar = struct.unpack_from("!HHHHHH", packet)
        if not flags & 0x8000 or (query_id is not None and qid != query_id):
            return []
        offset = 12
        for _ in range(qd):
            offset = _read_name(packet, offset)[1] + 4
        records = []
        for _ in range(an + ns + ar):
            rname, offset = _read_name(packet, offset)
            rtype, _rclass, _ttl, length = struct.unpack_from("!HHIH", packet, offset)
            offset += 10
            records.append((rname, rtype, packet[offset:offset + length]))
            offset += length
        return records
    except (struct.error, IndexError, UnicodeDecodeError, ValueError):
        return []


def addresses_of(records, name):
    """The A/AAAA addresses for ``name`` among ``records``, in order, without repeats."""
    found = []
    for rname, rtype, rdata in records:
        if rname.lower() == name.lower() and (rtype, len(rdata)) in ((TYPE_A, 4), (TYPE_AAAA, 16)):
            address = str(ipaddress.ip_address(rdata))
            if address not in found:
                found.append(address)
    return found


def parse_addresses(packet, name, query_id=None):
    """The A/AAAA addresses for ``name`` in a DNS response."""
    return addresses_of(parse_records(packet, query_id), name)


def _read_name(packet, offset):
    """(dotted name with trailing dot, offset after it), following compression pointers."""
    labels, end, jumps = [], None, 0
    while True:
        length = packet[offset]
        if length & 0xC0 == 0xC0:
            jumps += 1
            if jumps > 32:
                raise ValueError("DNS name pointer loop")
            if end is None:
                end = offset + 2
            offset = ((length & 0x3F) << 8) | packet[offset + 1]
        elif length == 0:
            return ".".join(labels) + ".", end if end is not None else offset + 1
        else:
            labels.append(packet[offset + 1:offset + 1 + length].decode("utf-8"))
            offset += 1 + length
