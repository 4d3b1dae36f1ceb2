"""The HTTP server: waitress, hardened for a robot anyone on the Wi-Fi can reach.

``server`` (the server and its connection policy), ``connection`` (one connection), ``lanes``
(who serves a request: the stop lane, the stream lane).
"""
