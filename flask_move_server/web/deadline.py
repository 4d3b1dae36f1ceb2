"""Motion commands that reach the robot late are refused, not driven.

A phone on a home Wi-Fi can lose touch for seconds without any socket closing: a goal dragged
in that time is delivered when the link comes back, long after the person let go (11.4 s in the
issue that asked for this). So ``/goto`` and ``/teleop`` take an optional ``valid_until``: a time
on the ROBOT's clock (seconds, ``time.monotonic()`` of the robot's process: it never jumps with
NTP and needs no clock agreement between phone and robot). The robot tells its clock in every
``clock`` event of ``GET /events`` (every two seconds) and in ``GET /status`` (``clock``); a client
adds the time a command may take (the page: 3 s for a goal, 1 s for the joystick) to its
estimate of the robot's clock now. A command read after that time answers 409 ``command_late``
and changes nothing. A deadline far ahead of the robot's clock is refused as a mistake (a wall
clock or milliseconds sent by accident), so a client cannot believe it is protected when it is not.
"""

import time

from flask_move_server.core.errors import BadRequest, CommandLate
from flask_move_server.web.body import number

FIELD = "valid_until"
MAX_AHEAD = 60.0  # s: a deadline further ahead than this is not a deadline, it is a mistake


def robot_clock():
    """The clock ``valid_until`` is read against: seconds, monotonic, rounded to a millisecond."""
    return round(time.monotonic(), 3)


def check_deadline(data, what):
    """Refuse ``what`` (e.g. "This goal") when ``data`` has a ``valid_until`` that has passed."""
    if FIELD not in data:
        return
    deadline = number(data, FIELD)
    now = time.monotonic()
    if deadline > now + MAX_AHEAD:
        raise BadRequest(
            "valid_until is {:.0f} s ahead of the robot's clock (now {:.3f}): it must be a time on the robot's "
            "clock, as told by GET /status 'clock' or the event stream's clock events, at most {:.0f} s "
            "ahead.".format(deadline - now, now, MAX_AHEAD))
    if now > deadline:
        raise CommandLate(
            "{} reached the robot {:.1f} s after its deadline (valid_until), so the robot did not act on it: "
            "the link to the robot was slow or stalled. Send it again if you still want it.".format(
                what, now - deadline))
