"""Telling the owner's home systems: MQTT (Home Assistant, VDA 5050) and webhooks beside it."""
