"""``robotctl``: the command-line client, its own package (it imports the library, never the reverse).

``cli`` (the commands, ``main``), ``api`` (the robot's HTTP API over requests), ``text`` (what it
prints), ``maps``, ``modes``, ``doctor`` (their commands), ``keyboard`` (``robotctl drive``).
"""
