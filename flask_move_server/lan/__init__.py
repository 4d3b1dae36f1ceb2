"""The robot on the local network: ``robot.local`` and its API over mDNS.

``mdns`` (the advertiser), ``records`` (its records, pure), ``dns_wire`` (DNS wire format),
``discovery`` (finding robots, for ``robotctl discover``).
"""
