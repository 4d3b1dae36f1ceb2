"""Stand-ins for what cannot run here: move_base's action server, the Pi's GPIO."""
