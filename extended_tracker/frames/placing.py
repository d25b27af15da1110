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

Scans leave in the order they came.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import Any, Callable

from .buffer import ConnectivityError, ExtrapolationError, planar, TiltError, Transform
from .pose import Placement

#: events of the scans the queue drops
PLACING_EVENTS = ('transform_late', 'transform_missing', 'tilted_scanner')
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
                 timeout: float, max_tilt: float):
        self.lookup, self.fixed_frame = lookup, fixed_frame
        self.timeout_ns, self.max_tilt = int(timeout * 1e9), max_tilt
        self.waiting: deque = deque()
        self.linked = False           # a scan has been placed in the fixed frame
        self.own_frame = False        # tracking in the scan frame (no link found)

    def push(self, scan, stamp_ns: int, frame: str, arrival_ns: int) -> None:
        self.waiting.append((scan, stamp_ns, frame, arrival_ns))

    def ready(self, now_ns: int) -> list[Placed]:
        """The scans that can leave at ``now_ns``, in order."""
        out = []
        while self.waiting:
            scan, stamp_ns, frame, arrival_ns = self.waiting[0]
            placed = self._try(scan, stamp_ns, frame, arrival_ns,
                               now_ns - arrival_ns >= self.timeout_ns)
            if placed is None:
                break
            self.waiting.popleft()
            out.append(placed)
        return out

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
