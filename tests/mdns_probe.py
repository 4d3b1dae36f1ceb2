"""What the mDNS tests run on the other host (inside the client network namespace).

``python -m tests.mdns_probe COMMAND ARGS...`` prints JSON on stdout:

- ``a-query NAME SECONDS``: a raw one-shot mDNS A query built and parsed with
  zeroconf's own DNSOutgoing/DNSIncoming (independent of lan/dns_wire.py's codec);
  prints the addresses that answered.
- ``browse TYPE``: a zeroconf ServiceBrowser; prints one line per event
  (``{"event": "added"|"updated"|"removed", "name", "port", "addresses"}``) until killed.
- ``discover SECONDS``: ``discovery.discover()``.
- ``get-local HOST PORT PATH``: ``discovery.resolve_local(HOST)``, then an HTTP GET
  (with ``Authorization: Bearer $ROBOT_TOKEN`` when set).
- ``advertise INSTANCE HOSTNAME PORT``: an :class:`~flask_move_server.lan.mdns.Advertiser`;
  prints what it published, withdraws when stdin closes.
"""

import json
import socket
import sys
import time

TYPE_A = CLASS_IN = 1  # RFC 1035 numbers (zeroconf's constants are private)


def _emit(value):
    print(json.dumps(value), flush=True)


def a_query(name, seconds):
    from zeroconf import DNSIncoming, DNSOutgoing, DNSQuestion

    out = DNSOutgoing(0, multicast=False, id_=4242)
    out.add_question(DNSQuestion(name, TYPE_A, CLASS_IN))
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.settimeout(float(seconds))
    found = []
    try:
        for packet in out.packets():
            sock.sendto(packet, ("224.0.0.251", 5353))
        while not found:
            data, _ = sock.recvfrom(9000)
            incoming = DNSIncoming(data)
            answers = incoming.answers() if callable(incoming.answers) else incoming.answers
            found = [socket.inet_ntoa(r.address) for r in answers
                     if r.type == TYPE_A and r.name.lower() == name.lower() and incoming.id == 4242]
    except socket.timeout:
        pass
    _emit(found)


def browse(service_type):
    from zeroconf import ServiceBrowser, ServiceStateChange, Zeroconf

    zc = Zeroconf()

    def on_change(zeroconf, service_type, name, state_change):
        event = {"event": state_change.name.lower(), "name": name}
        if state_change is not ServiceStateChange.Removed:
            info = zeroconf.get_service_info(service_type, name, timeout=1) or None
            if info is not None:
                event.update(port=info.port, addresses=info.parsed_addresses())
        _emit(event)

    browser = ServiceBrowser(zc, service_type, handlers=[_off_loop(on_change)])
    try:
        while True:
            time.sleep(1)
    finally:
        browser.cancel()
        zc.close()


def _off_loop(handler):
    """Handlers run on zeroconf's event loop; reading info there must not block it."""
    import threading

    def run(**kw):
        threading.Thread(target=handler, kwargs=kw, daemon=True).start()

    return run


def discover(seconds):
    from flask_move_server.lan import discovery

    _emit([r._asdict() for r in discovery.discover(float(seconds))])


def get_local(host, port, path):
    import os

    import requests

    from flask_move_server.lan import discovery

    address = discovery.resolve_local(host, timeout=3.0)
    result = {"address": address}
    if address:
        headers = {"Authorization": "Bearer " + os.environ["ROBOT_TOKEN"]} if os.environ.get("ROBOT_TOKEN") else {}
        response = requests.get("http://{}:{}{}".format(address, port, path), headers=headers, timeout=10)
        result.update(status=response.status_code, body=response.json())
    _emit(result)


def advertise(instance, hostname, port):
    import logging

    from flask_move_server.config import MdnsConfig
    from flask_move_server.lan.mdns import Advertiser

    logging.basicConfig(level=logging.INFO, stream=sys.stderr)
    settings = MdnsConfig(hostname=hostname, instance=instance, publish_hostname="always")
    advertiser = Advertiser(settings, "0.0.0.0", int(port), token_required=True).start()
    try:
        published = advertiser.wait_published(20)
        _emit(published._asdict() if published else None)
        sys.stdin.read()
    finally:
        advertiser.close()


COMMANDS = {"a-query": a_query, "browse": browse, "discover": discover, "get-local": get_local,
            "advertise": advertise}

if __name__ == "__main__":
    COMMANDS[sys.argv[1]](*sys.argv[2:])
