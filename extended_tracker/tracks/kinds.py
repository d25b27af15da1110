"""
What each reported track is: its motion state and a guess of its class, with how sure.

The guess rests on what the filter knows of the track, nothing else:

- *motion*: whether it has moved (travelled ``background.moved_distance`` beyond its first
  extent while seen, confirmed: the label the background protects), and its speed now;
- *extent and its history*: the semi-major axis, smoothed over ``SIZE_TIME``;
- *speed history*: the highest smoothed speed while it moved;
- *leg-pair structure*: whether it has ever been one of two part-sized labels moving
  together (:func:`pairs.join_pairs`: a walker's legs seen as two).

Motion state:

- ``NEVER_MOVED``: it has not moved since it was first reported;
- ``MOVING``: it has moved, and its speed is at least ``MOVING_SPEED``;
- ``PAUSED``: it has moved, and is slower now.

Class, and how sure (a fixed confidence per rule, not a calibrated probability):

- it has moved:
  - ``VEHICLE`` if it is longer than a person (smoothed semi-major at least
    ``VEHICLE_SEMI_AXIS``) or was faster than one (``VEHICLE_SPEED``): 0.8 with both, else
    0.6;
  - ``PERSON`` otherwise: 0.8, 0.9 with a leg pair;
- it has never moved:
  - ``PERSON`` with a leg pair: 0.6 (a chair's legs may look the same);
  - ``STATIC`` when it is thinner than a person's leg (a pole, ``THIN_SEMI_AXIS``) or
    larger than a person (``LARGE_SEMI_AXIS``): 0.7;
  - ``UNKNOWN`` otherwise, 0.5: a person standing still and a bin or a chair of their
    size look alike to a laser until one of them moves.

A paused person stays a person, and a label keeps its history while it is reported (a
label reported again after a scan without it starts over).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from .estimates import Estimates
from .record import find_sorted

NEVER_MOVED, MOVING, PAUSED = 0, 1, 2
UNKNOWN, PERSON, VEHICLE, STATIC = 0, 1, 2, 3
MOTION_NAMES = ('never moved', 'moving', 'paused')
CLASS_NAMES = ('unknown', 'person', 'vehicle', 'static')

MOVING_SPEED = 0.3         # m/s: slower than this, a track that has moved is paused
SIZE_TIME = 1.0            # s: time constant of the smoothed semi-major axis
SPEED_TIME = 0.5           # s: time constant of the smoothed speed
VEHICLE_SEMI_AXIS = 0.75   # m: a mover this long (1.5 m) is a vehicle
VEHICLE_SPEED = 3.5        # m/s: a mover this fast is a vehicle
THIN_SEMI_AXIS = 0.05      # m: a never-moved track this thin is a pole
LARGE_SEMI_AXIS = 0.6      # m: a never-moved track this large is no person


def _zeros(dtype=float):
    return field(default_factory=lambda: np.zeros(0, dtype))


@dataclass(frozen=True)
class TrackKinds:
    """Per reported label (ascending): whether it moved, its smoothed size and speed, the
    highest smoothed speed while it moved, and whether it was ever part of a leg pair."""

    label: np.ndarray = _zeros(np.int64)
    moved: np.ndarray = _zeros(bool)
    size: np.ndarray = _zeros()
    speed: np.ndarray = _zeros()
    top_speed: np.ndarray = _zeros()
    paired: np.ndarray = _zeros(bool)

    def updated(self, est: Estimates, dt: float, moved_labels: np.ndarray,
                pair_labels: np.ndarray) -> 'TrackKinds':
        """The history after a scan ``dt`` seconds on that reported ``est``;
        ``moved_labels`` are the labels seen to move, ``pair_labels`` those in a leg pair
        this scan."""
        order = np.argsort(est.label, kind='stable')
        label = est.label[order].astype(np.int64)
        semi = est.axes()[0][order] if len(est) else np.zeros(0)
        speed = np.hypot(est.m[order, 2], est.m[order, 3])
        at, known = find_sorted(self.label, label)
        k = at[known]
        size, smooth = semi.copy(), speed.copy()
        size[known] = _smooth(self.size[k], semi[known], dt, SIZE_TIME)
        smooth[known] = _smooth(self.speed[k], speed[known], dt, SPEED_TIME)
        moved = np.isin(label, moved_labels)
        paired = np.isin(label, pair_labels)
        top = np.where(moved, smooth, 0.0)
        moved[known] |= self.moved[k]
        paired[known] |= self.paired[k]
        top[known] = np.maximum(top[known], self.top_speed[k])
        return TrackKinds(label, moved, size, smooth, top, paired)

    def of(self, est: Estimates) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(motion, kind, confidence)`` of each of ``est``'s labels (a label these
        kinds do not hold: never moved, unknown, 0)."""
        n = len(est)
        motion, kind, conf = np.zeros(n, np.uint8), np.zeros(n, np.uint8), np.zeros(n)
        at, ok = find_sorted(self.label, est.label)
        for j in ok.nonzero()[0].tolist():
            i = at[j]
            speed = math.hypot(est.m[j, 2], est.m[j, 3])
            motion[j] = (NEVER_MOVED if not self.moved[i]
                         else MOVING if speed >= MOVING_SPEED else PAUSED)
            kind[j], conf[j] = guess(bool(self.moved[i]), float(self.size[i]),
                                     float(self.top_speed[i]), bool(self.paired[i]))
        return motion, kind, conf


def guess(moved: bool, size: float, top_speed: float, paired: bool) -> tuple[int, float]:
    """The class and its confidence from a track's history (see the module's notes)."""
    if moved:
        long_, fast = size >= VEHICLE_SEMI_AXIS, top_speed >= VEHICLE_SPEED
        if long_ or fast:
            return VEHICLE, 0.8 if long_ and fast else 0.6
        return PERSON, 0.9 if paired else 0.8
    if paired:
        return PERSON, 0.6
    if size < THIN_SEMI_AXIS or size > LARGE_SEMI_AXIS:
        return STATIC, 0.7
    return UNKNOWN, 0.5


def _smooth(old: np.ndarray, new: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """Exponential smoothing with time constant ``tau`` over a step of ``dt``."""
    gain = 1.0 - math.exp(-max(dt, 0.0) / tau)
    return old + gain * (new - old)


__all__ = ['TrackKinds', 'guess', 'NEVER_MOVED', 'MOVING', 'PAUSED', 'UNKNOWN', 'PERSON',
           'VEHICLE', 'STATIC', 'MOTION_NAMES', 'CLASS_NAMES']
