"""What the owner reads of a stuck robot: where, what it is doing about it, what to do. Pure.

A phone shows two lines of a banner, so each sentence starts with where the robot is and what
happens now; the reasons come after. Places are the owner's own names (the nearest marked place
within :data:`NEAR` metres), else x and y.
"""

import math

NEAR = 2.0  # m: a marked place this near names where the robot is


def place(pose, places):
    """``near office`` (the nearest of ``places``, ``(name, x, y)`` items) or ``at x 0.2, y 2.3``; None for no pose."""
    if pose is None:
        return None
    best = min(((math.hypot(x - pose.x, y - pose.y), name) for name, x, y in places), default=None)
    if best is not None and best[0] <= NEAR:
        return "near {}".format(best[1])
    return "at x {:.1f}, y {:.1f}".format(pose.x, pose.y)


def _where(where):
    return " {}".format(where) if where else ""


def blocked(where):
    return ("Stuck{}: its wheels turn but the laser sees it standing still (pressed against something?)."
            .format(_where(where)))


def cornered(where, on_the_map):
    """Goals aborted at once: ``on_the_map``, the footprint lies on a wall where the robot is localized;
    else the laser shows it touching something."""
    why = ("it is localized with its footprint on a wall of the map, so move_base can neither plan nor turn from "
           "here" if on_the_map else "its goals fail at once and the laser shows it touching something")
    return "Stuck{}: {}.".format(_where(where), why)


def pushed(where, way):
    return ("The robot is pressed against something {}{}: drive it the other way or turn it, or let it back out "
            "by itself.".format("ahead" if way > 0 else "behind", _where(where)))


def looking():
    return "Its goals fail at once: looking whether it is stuck."


def pressed(where):
    return ("Pressed against something{}: let it back out by itself, or drive it back with the joystick. Its "
            "wheels turned but the laser saw it standing still.".format(_where(where)))


def backing_out(where, distance, way=-1, again=True):
    """``way`` -1: backwards (the robot came forward into it); +1: forwards (it came backwards); ``again``:
    its goal is sent again after (else the owner asked, and it then waits)."""
    return "Stuck{}: {} {:.0f} cm slowly{}.".format(
        _where(where), "backing out" if way < 0 else "pulling out forwards", distance * 100,
        ", then trying again" if again else "")


def no_room(where):
    return ("Stuck{}: drive it out with the joystick (or move it by hand), then send it again. The way it came "
            "is not clear, so it did not back out.".format(_where(where)))


def no_way_out(where, why):
    return ("Stuck{}: drive it out with the joystick (or move it by hand), then send it again. {}"
            .format(_where(where), why))


def tried(times):
    return "It backed out {} time{} and got stuck again.".format(times, "" if times == 1 else "s")


def back_out_off():
    return "Backing out is off (stuck.back_out)."


def got_nowhere():
    return "It tried to back out but the laser saw it standing still."


def freed(where, target):
    return "Backed out{} and trying again{}.".format(_where(where), " to {}".format(target) if target else "")
