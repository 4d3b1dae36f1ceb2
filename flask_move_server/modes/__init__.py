"""Modes (idle, mapping, navigation): who runs the navigation stack, and switching between them."""
