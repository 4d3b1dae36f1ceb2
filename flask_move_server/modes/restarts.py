"""How a navigation stack that died by itself is restarted: how often, after how long. Pure.

A crash is restarted up to ``modes.restarts`` times, after 1, 2, then 4 s; the next crash
fails the mode. A stack that ran :attr:`RestartBudget.STABLE_RUN` seconds since it last
started has earned a fresh budget: its earlier crashes are forgiven.
"""


class RestartBudget:
    """The crash restarts a mode has used, and whether it may have another."""

    BACKOFF = (1.0, 2.0, 4.0)  # seconds before the 1st, 2nd, 3rd (and later) restart
    STABLE_RUN = 60.0  # seconds of running after which earlier crashes are forgiven

    def __init__(self, modes_config, clock):
        self._config = modes_config  # its ``restarts`` is read when needed, as the rest of the config is
        self.used = 0
        self._clock = clock
        self._running_since = None

    @property
    def limit(self):
        """Restarts allowed in a row (``modes.restarts``)."""
        return self._config.restarts

    def renew(self):
        """A switch by request: a full budget for the stack it starts."""
        self.used = 0

    def running(self):
        """The stack is up (first start or a restart): a stable run is timed from now."""
        self._running_since = self._clock()

    def crashed(self):
        """The running stack died: forgive earlier crashes after a stable run."""
        if self._running_since is not None and self._clock() - self._running_since >= self.STABLE_RUN:
            self.used = 0

    def take(self, message):
        """One more restart after ``message``; None when allowed, else why the mode failed."""
        self.used += 1
        if self.used <= self.limit:
            return None
        if not self.limit:
            return message
        return "failed after {} restart{}: {}".format(self.limit, "" if self.limit == 1 else "s", message)

    def delay(self):
        """Seconds to wait before the restart just taken."""
        return self.BACKOFF[min(self.used, len(self.BACKOFF)) - 1]

    def note(self, message):
        """What ``GET /mode`` says while the restart just taken is under way."""
        return "restarting ({} of {}) after: {}".format(self.used, self.limit, message)
