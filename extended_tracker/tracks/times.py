"""
How long each reported id has been shown, and how long since returns last updated it:
the age and time since detection that a consumer of tracks from a moving robot needs
(a track coasting through a shadow is shown, but not seen).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .estimates import Estimates
from .record import find_sorted


@dataclass(frozen=True)
class TrackTimes:
    """
    Per label (ascending): the stamp it was first shown at and the last stamp returns
    updated it at (ns). Kept while the label is shown; a label shown again after a scan
    without it starts over.
    """

    label: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    first_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    detected_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def updated(self, est: Estimates, stamp_ns: int) -> 'TrackTimes':
        """The times after a scan at ``stamp_ns`` that showed ``est``."""
        order = np.argsort(est.label, kind='stable')
        label = est.label[order].astype(np.int64)
        at, known = find_sorted(self.label, label)
        first = np.full(len(label), stamp_ns, np.int64)
        detected = np.full(len(label), stamp_ns, np.int64)
        first[known] = self.first_ns[at[known]]
        seen = est.num_detections[order] > 0
        detected[known & ~seen] = self.detected_ns[at[known & ~seen]]
        return TrackTimes(label, first, detected)

    def of(self, est: Estimates, stamp_ns: int) -> tuple[np.ndarray, np.ndarray]:
        """``(age, since_detected)`` (s) of each of ``est``'s labels at ``stamp_ns`` (0
        for a label these times do not hold)."""
        at, ok = find_sorted(self.label, est.label)
        age, since = np.zeros(len(est)), np.zeros(len(est))
        age[ok] = (stamp_ns - self.first_ns[at[ok]]) * 1e-9
        since[ok] = (stamp_ns - self.detected_ns[at[ok]]) * 1e-9
        return np.maximum(age, 0.0), np.maximum(since, 0.0)


__all__ = ['TrackTimes']
