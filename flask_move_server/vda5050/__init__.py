"""A VDA 5050 2.0.0 vehicle on the robot's MQTT connection: fleet managers drive it (docs/fleet.md)."""
