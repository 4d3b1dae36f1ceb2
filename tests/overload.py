"""Whether the machine was too busy for a test that waits on real time, said when such a test fails.

A test that waits on the simulated robot, a server process or a browser for a bounded real time
can fail only because the machine could not give it the time (other work: a load of 13-24 on two
cores). :func:`note` says so in the failure: the load against the cores, and what the ``--sim``
servers' worlds logged when they fell behind real time ("over the last 10 s the sim ran at 40 Hz
instead of 50 (0.81 of real time): machine overloaded", ``sim/world.py``). :func:`time_scale`
stretches the tests' time limits and the browser's waits on a machine overloaded (``conftest.py``).
"""

import os
import weakref

OVERLOADED = 2.0  # runnable tasks per core (the 1-minute load average) beyond which the machine is overloaded
SIM_BEHIND = "machine overloaded"  # what a --sim server's world logs when it fell behind real time
SERVERS = weakref.WeakSet()  # the ServerProcess objects alive, whose logs note() reads


def cores():
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def load_per_core():
    return os.getloadavg()[0] / cores()


def time_scale():
    """How many times longer to wait than on a quiet machine: 1 up to 4, by the load per core beyond OVERLOADED."""
    return min(4.0, max(1.0, load_per_core() / OVERLOADED))


def sim_lines():
    """What the live ``--sim`` servers' worlds logged when they fell behind real time."""
    return [line.strip() for server in list(SERVERS) for line in list(server.lines) if SIM_BEHIND in line]


def note():
    """Why a timing-sensitive failure may be the machine's, or "" when nothing says so."""
    lines = sim_lines()
    one, five, _ = os.getloadavg()
    if not lines and one / cores() <= OVERLOADED:
        return ""
    head = "load average {:.1f} (5 min: {:.1f}) on {} cores".format(one, five, cores())
    if one / cores() > OVERLOADED:
        head += ": machine overloaded, a test that waits on real time may fail for it alone"
    return "\n".join([head] + lines)
