"""The one behaviour that frees a wedged robot: a slow, straight back-out. Pure.

None of move_base's shipped recoveries moves a robot whose footprint touches the map (rotate
recovery refuses a turn with "a potential collision"; clearing the costmaps leaves the static
map). Backing out straight, the way it came, does (issue 33: 0.5 m by teleop freed it). Like
Nav2's ``back_up`` behaviour it is small and bounded: a distance, a speed, a time, and it stops
before the footprint comes within the clearance of anything the laser sees behind
(``footprint.room_along``) or when the laser sees it not moving.
"""

DONE, NO_ROOM, BLOCKED, TIMEOUT = "done", "no_room", "blocked", "timeout"
USEFUL = 0.1  # m: a back-out cut short after this much still counts (the robot came off what it touched)
SLACK = 2.0  # the time allowed: this many times distance / speed, plus a second to get going
PERIOD = 0.1  # s between two commands (the teleop deadman holds each for longer)


class BackOut:
    """One back-out of at most ``distance`` m at ``speed`` m/s: :meth:`next` says what to do now."""

    def __init__(self, distance, speed):
        self.distance, self.speed = distance, speed
        self.allowed = SLACK * distance / speed + 1.0

    def next(self, elapsed, backed, room, blocked):
        """The velocity to command now (negative: backwards), or how the back-out ended (DONE, NO_ROOM,
        BLOCKED, TIMEOUT): ``elapsed`` s since it began, ``backed`` m the odometry says it came, ``room``
        m still clear behind (None: no fresh scan), ``blocked`` when the laser saw it not moving."""
        if backed >= self.distance:
            return DONE
        if blocked:
            return BLOCKED
        if room is None or room <= 0.0:
            return DONE if backed >= USEFUL else NO_ROOM
        if elapsed > self.allowed:
            return DONE if backed >= USEFUL else TIMEOUT
        return -self.speed


def ended(step):
    """True when ``step`` (from :meth:`BackOut.next`) is an outcome, not a velocity."""
    return isinstance(step, str)
