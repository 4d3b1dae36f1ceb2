"""The robot on the owner's MQTT broker: one connection, Home Assistant discovery, commands, state (and webhooks)."""
