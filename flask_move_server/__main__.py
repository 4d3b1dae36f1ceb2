"""``python -m flask_move_server`` runs the server, like the console script."""

import sys

from flask_move_server.cli import main

sys.exit(main())
