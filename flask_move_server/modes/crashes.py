"""A mode's stack that dies by itself: restarted as the budget allows, else failed and its remains stopped.

:class:`StackCrashes` is the part of :class:`~flask_move_server.modes.manager.ModeManager` the
backend's ``on_exit`` reaches: a stack of the current switch that stopped while ``running`` is
restarted after the delay ``modes/restarts.py``'s budget gives (the mode ``starting`` meanwhile,
saying why), up to ``modes.restarts`` times in a row; after that the mode is ``failed`` and what is
left of the stack is stopped (roslaunch keeps a stack's other nodes running when one dies). It
reads and changes the manager's state under the manager's lock, as the manager's own methods do.
Pure: no rospy, no Flask.
"""

import logging

log = logging.getLogger(__name__)


class StackCrashes:
    """What ModeManager does when its stack dies by itself (a mixin: the manager's state and lock)."""

    def _on_exit(self, gen, message):
        """The backend's stack of switch ``gen`` died by itself: restart it, or give up."""
        with self._changed:
            if gen != self._gen or self._busy or self._closed or self._status["state"] != "running":
                return  # a stack we are stopping, or an old one
            log.warning("the %s stack stopped by itself: %s", self._target.mode, message)
            self.restart_budget.crashed()
            gave_up = not self._count_restart(message)
            self._busy = True
            self._gen += 1  # the restarted stack's exits carry the new number; the dead one's are ignored
            gen, target = self._gen, self._target
        if gave_up:
            self._spawn(self._stop_remains, gen)
        else:
            self._spawn(self._restart, gen, target, message)

    def _stop_remains(self, gen):
        """Failed for good: stop what is left of the stack (roslaunch and its other nodes, the lidar spinning)."""
        try:
            self._stop_stack()
        finally:
            self._done(gen)

    def _count_restart(self, message):
        """Under the lock: one more restart, or False when none is left (the mode is then failed)."""
        failure = self.restart_budget.take(message)
        if failure is not None:
            self._set(self._target, "failed", failure)
        return failure is None

    def _restart(self, gen, target, message):
        try:
            while True:
                note = self.restart_budget.note(message)
                with self._changed:
                    self._set(target, "starting", note)
                if self._closing.wait(self.restart_budget.delay()):
                    return
                self._stop_stack()
                message = self._start(gen, target, note, relocalize=False)
                with self._changed:
                    if message is None or not self._count_restart(message):
                        self._release(gen)
                        return
        finally:
            self._done(gen)
