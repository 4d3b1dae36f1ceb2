"""``python -m flask_move_server.systemd safe-stop``, named by units installed earlier: the safe stop.

sd_notify (readiness and watchdog) is :mod:`flask_move_server.app.systemd`; the units installed now
run ``python -m flask_move_server.drive.safe_stop``.
"""

import sys

from flask_move_server.app.systemd import main

if __name__ == "__main__":
    sys.exit(main())
