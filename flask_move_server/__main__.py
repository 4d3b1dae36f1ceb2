"""``python -m flask_move_server`` runs the server, like the console script."""

import sys

from flask_move_server.app.cli import main

sys.exit(main())
