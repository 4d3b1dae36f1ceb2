"""A route's timetable: ``"HH:MM"`` every day, or ``"mon,wed HH:MM"`` / ``"mon-fri HH:MM"``.

Times are the robot's local time (its time zone, as ``date`` shows it). :func:`parse` checks one
entry and gives its :class:`Slot`, written back in one canonical form (``"Mon-Fri 09:00"`` reads
as ``"mon-fri 09:00"``), so the file and the API say the same thing. Pure: no threads, no clock.
"""

import re
from dataclasses import dataclass
from datetime import datetime, time, timedelta

from flask_move_server.core.errors import BadRoute, shown

DAYS = ("mon", "tue", "wed", "thu", "fri", "sat", "sun")  # datetime.weekday() order
# ASCII digits and spaces only: "\d" would take Arabic-Indic or full-width digits as a time.
_ENTRY = re.compile(r"(?:(?P<days>[a-z,\-]+)[ \t]+)?(?P<hour>[0-9]{1,2}):(?P<minute>[0-9]{2})", re.ASCII)
MAX_TEXT = 64
EXAMPLES = "\"21:30\" (every day), \"mon-fri 09:00\" or \"sat,sun 10:15\" (24-hour clock, the robot's local time)"


@dataclass(frozen=True)
class Slot:
    """One entry: the weekdays (0 = Monday) and the minute of the day it starts a run."""

    days: frozenset
    hour: int
    minute: int
    text: str  # the canonical form, as kept and shown

    def matches(self, moment):
        """True when ``moment`` (a local datetime) is in this slot's minute on one of its days."""
        return moment.weekday() in self.days and (moment.hour, moment.minute) == (self.hour, self.minute)


def parse(entry):
    """The :class:`Slot` of one timetable entry; BadRoute saying what is wrong and what a time looks like."""
    if not isinstance(entry, str) or len(entry) > MAX_TEXT:
        raise BadRoute("Field 'schedule': each entry is a time as text, like {}; got {}.".format(
            EXAMPLES, shown(entry)))
    match = _ENTRY.fullmatch(entry.strip(" \t").lower())
    if match is None:
        raise BadRoute("Field 'schedule': {} is not a time; write {}.".format(shown(entry), EXAMPLES))
    hour, minute = int(match["hour"]), int(match["minute"])
    if hour > 23 or minute > 59:
        raise BadRoute("Field 'schedule': {} is not a time of day (00:00 to 23:59).".format(shown(entry)))
    days, days_text = _days(match["days"], entry)
    text = "{:02d}:{:02d}".format(hour, minute)
    return Slot(days, hour, minute, "{} {}".format(days_text, text) if days_text else text)


def _days(spec, entry):
    """(weekday numbers, canonical text) of ``mon,wed`` / ``mon-fri`` / ``sat,mon-wed``; all days for None.

    The text says each day once, in the week's order, three or more days in a row as a range:
    ``"mon,mon,mon"`` is ``"mon"``, ``"wed,mon-tue"`` is ``"mon-wed"``, every day is no days at all."""
    if spec is None:
        return frozenset(range(7)), ""
    days = set()
    for part in spec.split(","):
        first, _, last = part.partition("-")
        if first not in DAYS or (last and last not in DAYS):
            raise BadRoute("Field 'schedule': {} names a day it does not know; days are {} (\"mon-fri\", "
                           "\"sat,sun\").".format(shown(entry), ", ".join(DAYS)))
        a, b = DAYS.index(first), DAYS.index(last or first)
        days.update(range(a, b + 1) if a <= b else list(range(a, 7)) + list(range(0, b + 1)))
    return frozenset(days), _days_text(days)


def _days_text(days):
    """The canonical text of a set of weekday numbers ("" for every day); a span over the weekend stays one
    (``"fri-mon"``), written last."""
    if len(days) == 7:
        return ""
    spans = []
    for day in sorted(days):
        if spans and spans[-1][1] == day - 1:
            spans[-1][1] = day
        else:
            spans.append([day, day])
    if len(spans) > 1 and spans[0][0] == 0 and spans[-1][1] == 6:  # sunday runs on into monday
        spans[-1][1] = spans.pop(0)[1]
    parts = []
    for a, b in spans:
        run = [(a + i) % 7 for i in range((b - a) % 7 + 1)]
        parts.append("{}-{}".format(DAYS[a], DAYS[b]) if len(run) >= 3 else ",".join(DAYS[d] for d in run))
    return ",".join(parts)


def next_due(slots, after):
    """The next local datetime, strictly after ``after``, at which one of ``slots`` starts a run; None without slots.

    For the API's "next run". ``after`` is a local datetime (naive, or aware: the answer keeps its
    tzinfo). A time a daylight-saving change skips that day is still given: this module has no clock
    or zone to know it; the scheduler simply finds no such minute and runs nothing then.
    """
    candidates = [start for start in (_next_of(slot, after) for slot in slots) if start is not None]
    return min(candidates) if candidates else None


def _next_of(slot, after):
    """The first start of ``slot`` after ``after`` (a week and a day ahead at most), None for a slot of no day."""
    for ahead in range(8):
        day = after.date() + timedelta(days=ahead)
        start = datetime.combine(day, time(slot.hour, slot.minute), tzinfo=after.tzinfo)
        if day.weekday() in slot.days and start > after:
            return start
    return None
