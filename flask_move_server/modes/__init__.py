"""Modes idle, mapping and navigation: who runs the navigation stack, and switching between them."""
