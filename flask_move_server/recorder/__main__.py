"""``python -m flask_move_server.recorder``: the same as ``record-waypoints``."""

import sys

from flask_move_server.recorder import main

sys.exit(main())
