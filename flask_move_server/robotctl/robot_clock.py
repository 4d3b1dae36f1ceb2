"""The robot's clock as robotctl estimates it, for ``valid_until`` (docs/api.md, "Late commands").

``robotctl drive`` sends a joystick command a few times a second over Wi-Fi; one held up by a
stalled link must not drive the robot when it arrives. The robot tells its clock in ``GET /status``
(``clock``); the offset to ours is kept from the reading that arrived soonest (a delay only makes
the estimate early, so a window is never longer than asked for). A robot without a clock (an
older server) gets no ``valid_until``: commands then go as before.
"""

import time

from flask_move_server.core.errors import ClientError


class RobotClock:
    def __init__(self, client):
        self.client = client
        self.offset = None

    def sync(self):
        """Read the robot's clock once; True when it told one."""
        asked = time.monotonic()
        try:
            clock = self.client.get("/status").get("clock")
        except ClientError:
            return False
        if not isinstance(clock, (int, float)) or isinstance(clock, bool):
            return False
        offset = clock - asked  # asked, not answered: the reading is no older than the question
        if self.offset is None or offset > self.offset:
            self.offset = offset
        return True

    def deadline(self, seconds):
        """``{"valid_until": …}`` ``seconds`` from now on the robot's clock, or {} when it is unknown."""
        if self.offset is None:
            return {}
        return {"valid_until": round(time.monotonic() + self.offset + seconds, 3)}
