"""Telling the owner's home systems: MQTT (Home Assistant, VDA 5050; one connection) and webhooks beside it."""
