"""
The record of the ids shown: how long each label has been reported, where it was
shown, which labels pair up. Track management (:mod:`tracks.manage`) keeps it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..config import ExtractionConfig
from ..filter.tables import read_only

NO_LABELS = read_only(np.zeros(0, np.int64))[0]
#: a label reported this many scans in a row is old; settled if it has not moved
SETTLED_SCANS = 20


@dataclass(frozen=True)
class TrackRecord:
    """
    The bookkeeping of the ids a user sees, carried from scan to scan.

    Attributes
    ----------
    reported : (r,) int64 array
        Labels extracted in the last scan, ascending (reported once confirmed, see
        :meth:`confirmed_rows`); ``reported_scans`` counts consecutive scans,
        ``reported_hits`` how many of those returns updated it in (its birth scan
        included; a label split off another's far component counts from its next scan,
        the returns of the split scan having updated the other label),
        ``reported_origin`` (r, 2) is where each was first reported, ``reported_size``
        (r,) its semi-major axis then, and ``reported_travel`` (r,) the farthest it has
        been from there in a scan where returns updated it (m; coasting drift does not
        count).
    shown : (s,) int64 array
        Labels ever reported (shown to the user) that are still in the mixture or were
        shown less than ``extraction.handover_time`` ago, ascending; ``shown_pos`` (s, 2)
        is where each was last shown, ``shown_vel`` (s, 2) its velocity then and
        ``shown_elapsed`` (s,) how long ago (s). A label's next report must be reachable
        from there within ``extraction.max_speed`` and ``extraction.max_accel`` or it is a
        new object.
    label_clock : tuple of (float, int)
        ``(seconds ago, next_label then)`` at the start of each scan of the last
        ``extraction.handover_time`` seconds, oldest first: labels from the first
        ``next_label`` on were created in that time.
    pairs : (k, 2) int64 array
        Pairs of labels (smaller first) extracted as close parts in the last scan, and
        ``pair_runs`` (k,) in how many scans in a row (see :func:`pairs.join_pairs`).

    """

    reported: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    reported_scans: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    reported_origin: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    reported_travel: np.ndarray = field(default_factory=lambda: np.zeros(0))
    reported_size: np.ndarray = field(default_factory=lambda: np.zeros(0))
    reported_hits: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    shown: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    shown_pos: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    shown_vel: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    shown_elapsed: np.ndarray = field(default_factory=lambda: np.zeros(0))
    label_clock: tuple = ()
    pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    pair_runs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    def confirmed_rows(self, ex: ExtractionConfig) -> np.ndarray:
        """
        Which ``reported`` labels are confirmed: extracted ``ex.confirm_scans`` scans in a
        row and updated by returns in ``ex.confirm_detections`` of them (M of N).

        A static spot that returns now and then (a far edge, a half-seen table leg) makes a
        label from one scan's returns that the filter keeps extracting for a few scans
        while it coasts; counting the scans alone showed it as an object for a scan or two,
        again each time the spot returned.
        """
        return ((self.reported_scans >= ex.confirm_scans)
                & (self.reported_hits >= ex.confirm_detections))

    def settled_rows(self, moved_distance: float) -> np.ndarray:
        """Which ``reported`` labels are settled: reported ``SETTLED_SCANS`` scans in a row
        and never ``moved_distance`` from where they were first reported (a chair, a post,
        a person standing still)."""
        return (self.reported_scans >= SETTLED_SCANS) & (self.reported_travel < moved_distance)

    def confirmed_labels(self, ex: ExtractionConfig) -> np.ndarray:
        """The confirmed labels (:meth:`confirmed_rows`), ascending."""
        return self.reported[self.confirmed_rows(ex)]

    def confirmed_travel(self, labels: np.ndarray, ex: ExtractionConfig) -> np.ndarray:
        """
        How far (m) each of ``labels`` has travelled beyond its own first extent (its
        semi-major axis when first reported), for those confirmed (:meth:`confirmed_rows`);
        -1 for the others. A static object whose returns are learned as background one
        side after the other sees its centre shift by up to its own size; that is not
        travel.
        """
        out = np.full(len(labels), -1.0)
        if len(labels) and len(self.reported):
            at, found = find_sorted(self.reported, labels)
            ok = found & self.confirmed_rows(ex)[at]
            out[ok] = np.maximum(self.reported_travel[at[ok]] - self.reported_size[at[ok]],
                                 0.0)
        return out


def find_sorted(ascending: np.ndarray, a: np.ndarray):
    """
    ``(at, found)``: where each of ``a`` is in the ascending array ``ascending`` and
    whether it is there at all (``at`` is a valid index either way). For the few labels
    of a scan: ``np.isin`` would sort both arrays again.
    """
    if not len(ascending):
        return np.zeros(len(a), dtype=np.int64), np.zeros(len(a), dtype=bool)
    at = np.minimum(ascending.searchsorted(a), len(ascending) - 1)
    return at, ascending[at] == a
