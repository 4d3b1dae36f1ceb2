"""Goals only while a stack that takes them runs: the modes' side of every goal.

A goal sent in the ~200 ms a switch takes to begin reached the stack going away (or none), was
answered 202 and stayed ``active`` for good: no stack ran it, ``/stop`` left it ``canceling``,
and a waiting ``/goto`` waited its whole timeout. So a goal is admitted only while the mode runs
a stack with move_base; one under way when a switch begins is given up with the reason; and one
sent as a switch began (between its admission and its send) is given up at once.
"""

from flask_move_server.core.errors import NavigationUnavailable, WrongMode

IDLE_REFUSAL = ("The robot is idle: no navigation stack runs, so nothing takes goals. Start navigation on a map "
                "first: POST /mode {\"mode\": \"navigation\", \"map\": NAME} (robotctl map use NAME; GET /maps "
                "lists the maps).")
FOREIGN_MOVE_BASE = ("move_base is running but was not started by this server (your own launch files?), and this "
                     "server's mode is idle, so it sends it no goals. To send goals to your own move_base, set "
                     "modes.stack: none in the server's config and restart it; to let this server run the stack, "
                     "stop yours and start navigation: POST /mode {\"mode\": \"navigation\"}.")
SWITCHED = ("The robot switched to {}, which stops the stack that had the goal: it was given up. Send it again "
            "once GET /mode says running.")


class GoalGate:
    """Admits goals for the mode manager ``modes`` and gives up ``navigator``'s goal when a switch begins."""

    def __init__(self, modes, navigator):
        self._modes = modes
        self._navigator = navigator
        modes.when_leaving_running(self._switching)

    def admit(self):
        """A ticket for a goal sent now; WrongMode (idle) or NavigationUnavailable (switching, failed) say why not."""
        status, ticket = self._modes.status_and_generation()
        refusal = self._refusal(status)
        if refusal is not None:
            raise refusal
        return ticket

    def open_now(self):
        """True when a goal sent now would be admitted."""
        status, _ = self._modes.status_and_generation()
        return self._refusal(status) is None

    def confirm(self, ticket, seq):
        """Goal ``seq`` was sent with ``ticket``: give it up if a switch began meanwhile."""
        status, now = self._modes.status_and_generation()
        if now != ticket:
            self._navigator.abandon(SWITCHED.format(_describe(status)), "a mode switch began as it was sent", seq)

    def _switching(self, status):
        """A switch begins: the goal under way is given up (``aborted``, saying why); a goal that
        had ended is old news on the new map (the page said "arrived at kitchen" on a map without
        a kitchen): set aside, ``/status`` says idle."""
        if not self._navigator.abandon(SWITCHED.format(_describe(status)), "the mode is switching"):
            self._navigator.set_aside()

    def foreign_move_base(self):
        """True when the mode is idle (and settled) yet a move_base answers: one this server did not start."""
        status, _ = self._modes.status_and_generation()
        return status["mode"] == "idle" and status["state"] == "running" and self._navigator.server_ready()

    def health_note(self):
        """What ``GET /health`` adds for the owner (a move_base this server did not start), or None."""
        return FOREIGN_MOVE_BASE if self.foreign_move_base() else None

    def _refusal(self, status):
        if status["mode"] == "idle":  # the owner's choice, not a failure: 409 like POST /pose
            return WrongMode(FOREIGN_MOVE_BASE if self.foreign_move_base() else IDLE_REFUSAL)
        if status["state"] in ("starting", "stopping"):
            return NavigationUnavailable("The {} stack is {}: send the goal again once GET /mode says running."
                                         .format(status["mode"], status["state"]))
        if status["state"] == "failed":
            return NavigationUnavailable("The {} stack failed: {}. Switch again once that is fixed (POST /mode)."
                                         .format(status["mode"], (status["message"] or "see GET /mode").rstrip(".")))
        if not self._modes.takes_goals(status["mode"]):
            return NavigationUnavailable("The {} stack runs no move_base, so nothing takes goals."
                                         .format(status["mode"]))
        return None


def _describe(status):
    return status["mode"] + (" on " + status["map"] if status.get("map") else "")
