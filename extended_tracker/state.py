"""
What the filter carries from scan to scan and what it reports.

:class:`FilterState` is data, passed into a filter step and returned by it (the mixture,
the cardinality pmf and the record of the ids shown); :class:`Estimates` are the objects
one scan reports; :class:`StepDiagnostics` counts what a step did.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .config import ExtractionConfig, TrackerConfig
from .ggiw import eig2, Mixture
from .tables import read_only

NEG_INF = -np.inf
NO_LABELS = read_only(np.zeros(0, np.int64))[0]


@dataclass(frozen=True)
class Estimates:
    """
    Reported objects of one scan, arrays with a leading object axis of length ``k``.

    Attributes
    ----------
    label : (k,) int64
    existence : (k,) weight of the label, clipped to [0, 1]
    m : (k, 4) kinematic mean; P : (k, 4, 4) its covariance
    X : (k, 2, 2) expected extent matrix (m^2)
    rate : (k,) expected detections per scan
    num_detections : (k,) detections that updated the label this scan
    visibility : (k,) visible fraction used for p_D (1 where not computed)

    """

    label: np.ndarray
    existence: np.ndarray
    m: np.ndarray
    P: np.ndarray
    X: np.ndarray
    rate: np.ndarray
    num_detections: np.ndarray
    visibility: np.ndarray

    def __len__(self):
        return int(self.label.shape[0])

    def take(self, idx) -> 'Estimates':
        """The objects at ``idx`` (index array or boolean mask)."""
        return Estimates(self.label[idx], self.existence[idx], self.m[idx],
                         self.P[idx], self.X[idx], self.rate[idx],
                         self.num_detections[idx], self.visibility[idx])

    def axes(self):
        """Semi-major, semi-minor (m) and yaw of the major axis (rad) of each extent."""
        return self._axes

    @cached_property
    def _axes(self):
        # computed once per scan's estimates, read by messages, markers, shapes and plots
        # (shared, so read-only)
        lam1, lam2 = eig2(self.X)
        yaw = 0.5 * np.arctan2(2 * self.X[:, 0, 1], self.X[:, 0, 0] - self.X[:, 1, 1])
        return read_only(np.sqrt(lam1), np.sqrt(np.maximum(lam2, 0.0)), yaw)

    def rectangle(self):
        """
        Length and width of the oriented rectangle with the ellipse's second moments.

        Notes
        -----
        A filled ellipse of semi-axis ``a`` has second moment ``a^2/4`` along it; a filled
        rectangle of side ``L`` has ``L^2/12``; equal moments give ``L = sqrt(3) a``.
        """
        major, minor, _ = self.axes()
        return np.sqrt(3.0) * major, np.sqrt(3.0) * minor

    @staticmethod
    def empty():
        """Return estimates with no object."""
        return Estimates(np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 4)),
                         np.zeros((0, 4, 4)), np.zeros((0, 2, 2)), np.zeros(0),
                         np.zeros(0, np.int64), np.zeros(0))


@dataclass(frozen=True)
class FilterState:
    """
    Everything the filter carries from one scan to the next.

    Attributes
    ----------
    mixture : Mixture
        Posterior GGIW mixture.
    log_card : (N_max + 1,) array
        Posterior cardinality pmf (log).
    next_label : int
        Next unused track label.
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
        ``pair_runs`` (k,) in how many scans in a row (see :func:`identity.join_pairs`).

    """

    mixture: Mixture
    log_card: np.ndarray
    next_label: int = 1
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
    dt: float = 0.1

    @staticmethod
    def initial(cfg: TrackerConfig) -> 'FilterState':
        """An empty scene: no components, cardinality certainly zero."""
        log_card = np.full(cfg.model.n_max + 1, NEG_INF)
        log_card[0] = 0.0
        return FilterState(Mixture.empty(), log_card)

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


@dataclass
class StepDiagnostics:
    """Counts of one filter step (filled by update_state)."""

    detections: int = 0
    partitions: int = 0
    cells: int = 0
    pairs: int = 0
    components: int = 0
    births: int = 0
    capped_partitions: int = 0
    capped_cells: int = 0
    capped_components: int = 0
    oversized: int = 0
    fused_labels: int = 0
    joined_labels: int = 0
    relabelled: int = 0
    handed_over: int = 0
    grouped: int = 0
    unexplained: int = 0
    held: int = 0
    sparse_births: int = 0


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
