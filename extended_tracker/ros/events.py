"""
The node's event log: every event counted, each new kind of reason said at once, the
rest summarised once a period. Plain Python (no rclpy), so it is tested on its own.

An event's reason names what went wrong with the figures of that scan (``len(ranges) =
0 disagrees with ... 1081 beams``, ``2.500 s since the previous scan``). Two reasons that
differ only in their figures are one kind: the first is logged, the others counted. A
reason of another kind is logged at once, however soon after the first (a driver sending
two kinds of broken scan shows both). What was counted but not logged is summarised by
:meth:`EventLog.summary_lines`, which the node calls every ``period`` seconds.

Two counters feed it: :class:`ScanGaps` (scans missing between stamps) and :class:`Pace`
(scans in a row that took longer than the scan period).
"""

from __future__ import annotations

import re

# reasons of one event that differ only in numbers are one kind of reason
_FIGURES = re.compile(r'[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?')
# at most this many kinds of reason logged at once per event; the rest are summarised
MAX_KINDS = 20


def reason_kind(reason: str) -> str:
    """The reason with its figures taken out."""
    return _FIGURES.sub('#', reason)


class EventLog:
    """Counts of the node's events, their last reasons, and what to log when."""

    def __init__(self):
        self.counts: dict[str, int] = {}
        self.last_reason: dict[str, str] = {}
        self._kinds: dict[str, set] = {}
        self._unsaid: dict[str, int] = {}

    def record(self, event: str, reason: str) -> str | None:
        """Count one ``event``; the line to log now (its first, or a new kind of reason)
        or None (it is counted for the next summary)."""
        n = self.counts.get(event, 0) + 1
        self.counts[event] = n
        self.last_reason[event] = reason
        kinds = self._kinds.setdefault(event, set())
        kind = reason_kind(reason)
        if kind not in kinds and len(kinds) < MAX_KINDS:
            kinds.add(kind)
            more = ('counted; further ones are summarised every 10 s' if n == 1 else
                    f'{n} so far')
            return f'{event}: {reason} ({more})'
        self._unsaid[event] = self._unsaid.get(event, 0) + 1
        return None

    def summary_lines(self) -> list[str]:
        """One line per event counted since the last summary and not logged then."""
        lines = [f'{event}: {k} more since the last summary ({self.counts[event]} in all); '
                 f'last: {self.last_reason[event]}'
                 for event, k in sorted(self._unsaid.items())]
        self._unsaid.clear()
        return lines


class ScanGaps:
    """
    Scans missing between the stamps of those that arrive, from the scanner's period:
    the driver's ``scan_time`` where it gives one, else the shortest of the last
    ``window`` stamp steps (once ``min_steps`` are known; in a burst that the queue
    thinned, most steps are long and only the shortest is the scanner's).

    A step of ``k`` periods (k >= 1.5, rounded) means ``k - 1`` scans that never reached
    the callback: the subscription's queue dropped them while the node was busy (a burst
    faster than it can keep up with), or the driver or the network lost them. Steps back
    and repeats are the pipeline's events, not gaps.
    """

    def __init__(self, window: int = 20, min_steps: int = 3, ratio: float = 1.5):
        self.window, self.min_steps, self.ratio = window, min_steps, ratio
        self._steps: list[int] = []
        self._last: int | None = None
        self.total = 0

    def missing(self, stamp_ns: int, scan_time: float = 0.0) -> int:
        """The scans missing just before the one stamped ``stamp_ns`` (``scan_time``: the
        scan period the driver gives, s; 0 when it gives none)."""
        last, self._last = self._last, stamp_ns
        if last is None or stamp_ns <= last:
            return 0
        step = stamp_ns - last
        self._steps = (self._steps + [step])[-self.window:]
        period = scan_time * 1e9 if scan_time > 0 else (
            min(self._steps) if len(self._steps) >= self.min_steps else None)
        missing = 0
        if period and step >= self.ratio * period:
            missing = round(step / period) - 1
        self.total += missing
        return missing


class Pace:
    """
    Whether the node keeps up: ``slow_scans`` scans in a row whose callback took longer
    than the time from the previous scan's stamp to theirs (a stamp that goes back gives
    no period, and starts the count again, as a scan that kept up does).
    """

    def __init__(self, slow_scans: int):
        self.slow_scans = slow_scans
        self._last: int | None = None
        self._in_a_row = 0

    def falling_behind(self, stamp_ns: int, took: float) -> float | None:
        """The scan period (s) when this scan, which took ``took`` s, is the
        ``slow_scans``-th slow one in a row (the count then starts again); else None."""
        last, self._last = self._last, stamp_ns
        period = (stamp_ns - last) * 1e-9 if last is not None and stamp_ns > last else None
        if period is None or took <= period:
            self._in_a_row = 0
            return None
        self._in_a_row += 1
        if self._in_a_row < self.slow_scans:
            return None
        self._in_a_row = 0
        return period
