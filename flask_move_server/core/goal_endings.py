"""Why a navigation goal ended without the robot arriving, in the one sentence everyone says.

The server answers a ``/goto`` with ``wait`` that fails with it (409 ``navigation_failed``), and
``robotctl goto --wait`` prints it when it sees the goal end in ``/status``; both read it here,
so a user meets the same words whichever way they sent the goal. Pure: no rospy, no Flask.
"""

_SENTENCES = {
    "aborted": "move_base aborted the goal{to}: no path was found or the robot got stuck.",
    "rejected": "move_base rejected the goal{to}: is it inside the map?",
    "canceled": "The goal{to} was canceled before the robot arrived.",
    "canceling": "The goal{to} was canceled before the robot arrived.",
    "idle": "The goal{to} is gone (the server restarted?).",
    "stuck": "The robot got stuck on its way{to} and could not get itself out.",
}


def failure_sentence(state, target=None):
    """The sentence for a goal to ``target`` (a waypoint name, or None) that ended in ``state``.

    Any state without a sentence of its own (``lost``, ``preempted``, ...) reads as aborted:
    the robot did not arrive and nobody asked it to stop.
    """
    return _SENTENCES.get(state, _SENTENCES["aborted"]).format(to=_to(target))


def replaced_sentence(target=None):
    """The sentence for a goal to ``target`` that a newer goal took the place of while under way."""
    return "The goal{} was replaced by a newer goal.".format(_to(target))


def said_sentence(state, target, said):
    """The sentence for a goal that move_base ended in ``state`` giving its own reason ``said``.

    move_base's words replace the guess ("no path was found or the robot got stuck"): a goal
    ended because the navigation stack was stopped for a mode switch says so.
    """
    verb = "rejected" if state == "rejected" else "aborted"
    stop = "" if said.endswith((".", "!", "?")) else "."
    return "move_base {} the goal{}: {}{}".format(verb, _to(target), said, stop)


def replaced_end(state, message, target):
    """``(state, sentence)`` for a waiting client of a goal a newer one replaced, from the goal's last
    ``state`` and ``message`` then: under way (``active``) reads ``canceled``, "replaced by a newer
    goal"; one that had ended answers its own end (no sentence when it arrived)."""
    if state in ("active", "idle"):
        return "canceled", replaced_sentence(target)
    if state == "succeeded":
        return state, None
    return state, message or failure_sentence(state, target)


def _to(target):
    """`` to 'kitchen'`` for a goal to a waypoint; nothing for a goal to x, y."""
    return " to {!r}".format(target) if target else ""
