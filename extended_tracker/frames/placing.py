"""
Scans waiting for their transform into the fixed frame: the same queue for the live node
(its clock, fed by ``/tf``) and the bag replay (the bag's record time, fed by the bag).

A scan is placed with the scanner's pose at its own stamp, interpolated, never the
latest pose. Each outcome is a :class:`Placed`:

- the transform is there: the scan is placed in the fixed frame;
- the transform is not there yet (the newest data is older than the stamp): the scan
  waits, up to ``tf.timeout`` after it arrived, then is dropped (``transform_late``);
- the stamp is older than the data kept (``transform_missing``), the scan plane is
  tilted over ``tf.max_tilt`` (``tilted_scanner``): dropped at once;
- no transform links the scan frame to the fixed frame at all: while that has never
  worked, the scan is tracked in its own frame after the wait (a stationary scanner with
  no TF), event ``no_fixed_frame``; once it has, the scan is dropped
  (``transform_missing``). When a link appears after tracking in the scan frame, the
  tracks move to the fixed frame (event ``fixed_frame_found``: the caller restarts them).

Scans leave in the order of their stamps. Once several scanners feed the queue, each
scan is held ``timing.latency`` after it arrived, so that one that arrives a little
late is put in its place; one older than a scan already left (by at most
``timing.max_gap``: more is a clock that jumped, the pipeline's to handle) is dropped
(``scan_out_of_order``).
"""

from __future__ import annotations

from bisect import insort
from dataclasses import dataclass
from typing import Any, Callable

from .buffer import ConnectivityError, ExtrapolationError, planar, TiltError, Transform
from .pose import Placement

#: events of the scans the queue drops
PLACING_EVENTS = ('transform_late', 'transform_missing', 'tilted_scanner', 'scan_out_of_order')
#: what the queue says once of the frame the tracks are kept in (no event of a scan)
NOTICES = ('no_fixed_frame', 'fixed_frame_found')


@dataclass(frozen=True)
class Placed:
    """
    A scan out of the queue: where it was taken (None: in its own frame), or, when
    ``dropped``, not to be tracked; ``event`` and ``error`` say why when special.
    """

    scan: Any
    arrival_ns: int
    place: Placement | None
    dropped: bool = False
    event: str | None = None
    error: str | None = None


class ScanPlacer:
    """
    The queue. ``lookup(target, source, stamp_ns)`` gives a :class:`buffer.Transform` or
    raises a :class:`buffer.TransformError` (the project's buffer, or tf2 adapted).
    """

    def __init__(self, lookup: Callable[[str, str, int], Transform], fixed_frame: str,
                 timeout: float, max_tilt: float, latency: float = 0.0,
                 max_gap: float = 2.0):
        self.lookup, self.fixed_frame = lookup, fixed_frame
        self.timeout_ns, self.max_tilt = int(timeout * 1e9), max_tilt
        self.latency_ns, self.max_gap_ns = int(latency * 1e9), int(max_gap * 1e9)
        self.waiting: list = []       # (stamp, order, scan, frame, arrival) by stamp
        self.pushed = 0
        self.frames: set = set()      # the scanners placed in the fixed frame
        self.last_ns: int | None = None   # the stamp of the last scan to leave
        self.linked = False           # a scan has been placed in the fixed frame
        self.own_frame = False        # tracking in the scan frame (no link found)

    def push(self, scan, stamp_ns: int, frame: str, arrival_ns: int) -> None:
        insort(self.waiting, (stamp_ns, self.pushed, scan, frame, arrival_ns),
               key=lambda w: w[:2])
        self.pushed += 1

    def ready(self, now_ns: int) -> list[Placed]:
        """The scans that can leave at ``now_ns``, in the order of their stamps."""
        out = []
        hold = self.latency_ns if len(self.frames) > 1 else 0
        while self.waiting:
            stamp_ns, _, scan, frame, arrival_ns = self.waiting[0]
            if now_ns - arrival_ns < hold:
                break
            placed = self._late(scan, stamp_ns, arrival_ns) or self._try(
                scan, stamp_ns, frame, arrival_ns, now_ns - arrival_ns >= self.timeout_ns)
            if placed is None:
                break
            self.waiting.pop(0)
            if not placed.dropped:
                self.last_ns = stamp_ns
            out.append(placed)
        return out

    def _late(self, scan, stamp_ns: int, arrival_ns: int) -> Placed | None:
        """The drop of a scan older than one that already left (within ``max_gap``), once
        several scanners feed the queue (one scanner's step back is the pipeline's
        ``time_backwards``)."""
        if (len(self.frames) < 2 or self.last_ns is None
                or not 0 < self.last_ns - stamp_ns <= self.max_gap_ns):
            return None
        return Placed(scan, arrival_ns, None, True, 'scan_out_of_order',
                      f'stamped {(self.last_ns - stamp_ns) * 1e-9:.3f} s before a scan already '
                      f'tracked: it came more than timing.latency late; not tracked')

    def flush(self) -> list[Placed]:
        """Every scan still waiting, as if its wait were over (the end of a bag)."""
        return self.ready(2 ** 62)

    def _try(self, scan, stamp_ns: int, frame: str, arrival_ns: int, waited: bool):
        try:
            pose = planar(self.lookup(self.fixed_frame, frame, stamp_ns), self.max_tilt)
        except TiltError as err:
            return Placed(scan, arrival_ns, None, True, 'tilted_scanner',
                          f'{frame}: {err}; the scan is not tracked')
        except ExtrapolationError as err:
            if err.future and not waited:
                return None
            kind = 'transform_late' if err.future else 'transform_missing'
            return Placed(scan, arrival_ns, None, True, kind,
                          f'no transform {self.fixed_frame} <- {frame} at the scan\'s '
                          f'stamp: {err}; the scan is not tracked')
        except ConnectivityError as err:
            return self._unlinked(scan, frame, arrival_ns, waited, err)
        found = self.own_frame
        self.linked, self.own_frame = True, False
        self.frames.add(frame)
        place = Placement(self.fixed_frame, pose)
        if found:
            return Placed(scan, arrival_ns, place, False, 'fixed_frame_found',
                          f'{frame} is now linked to {self.fixed_frame}: the tracks '
                          f'restart there')
        return Placed(scan, arrival_ns, place)

    def _unlinked(self, scan, frame: str, arrival_ns: int, waited: bool, err):
        if self.linked:
            return Placed(scan, arrival_ns, None, True, 'transform_missing',
                          f'{err}; the scan is not tracked')
        if self.own_frame:
            return Placed(scan, arrival_ns, None)
        if not waited:
            return None
        self.own_frame = True
        return Placed(scan, arrival_ns, None, False, 'no_fixed_frame',
                      f'{err}: tracking in the scan frame {frame!r}, the scanner taken '
                      f'to stand still')


__all__ = ['ScanPlacer', 'Placed', 'PLACING_EVENTS', 'NOTICES']
