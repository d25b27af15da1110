"""
Evaluation metrics: GOSPA with the Gaussian-Wasserstein base distance, cardinality error,
id switches and track fragmentation (numpy/scipy only).

Notes
-----
Gaussian-Wasserstein distance between ellipses (centre ``m``, extent matrix ``X``)::

    d(1, 2)^2 = |m1 - m2|^2 + tr(X1 + X2 - 2 (X1^1/2 X2 X1^1/2)^1/2)

GOSPA (Rahmathullah, García-Fernández, Svensson, FUSION 2017) with ``alpha = 2``,
cut-off ``c`` and order ``p``, the base distance being ``d`` itself (not its square, and
cut at ``c`` after the square root: trap 6 of the model note)::

    GOSPA = ( min_assignment sum_assigned d^p  +  c^p / 2 (missed + false) )^(1/p)

where only pairs with ``d < c`` are assigned. The localisation, missed and false parts
below are the three terms of the sum (before the 1/p power).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..filter.algebra2 import sqrtm_spd2


def gw_distance(m1, X1, m2, X2) -> np.ndarray:
    """Gaussian-Wasserstein distances between all pairs: (n1, n2) array, metres."""
    m1, m2 = np.asarray(m1, float).reshape(-1, 2), np.asarray(m2, float).reshape(-1, 2)
    X1, X2 = np.asarray(X1, float).reshape(-1, 2, 2), np.asarray(X2, float).reshape(-1, 2, 2)
    if not len(m1) or not len(m2):
        return np.zeros((len(m1), len(m2)))
    dm = ((m1[:, None, :] - m2[None, :, :]) ** 2).sum(-1)
    r1 = sqrtm_spd2(X1)                                        # (n1, 2, 2)
    inner = r1[:, None] @ X2[None, :] @ r1[:, None]            # (n1, n2, 2, 2)
    # symmetrise against rounding, then the PSD square root (2x2 closed form)
    inner = 0.5 * (inner + np.swapaxes(inner, -1, -2))
    det = np.maximum(inner[..., 0, 0] * inner[..., 1, 1] - inner[..., 0, 1] ** 2, 0.0)
    tr_sqrt = np.sqrt(np.maximum(inner[..., 0, 0] + inner[..., 1, 1] + 2 * np.sqrt(det), 0.0))
    tr = np.trace(X1, axis1=-2, axis2=-1)[:, None] + np.trace(X2, axis1=-2, axis2=-1)[None, :]
    return np.sqrt(np.maximum(dm + tr - 2 * tr_sqrt, 0.0))


@dataclass(frozen=True)
class Gospa:
    """GOSPA of one scan and its parts (``total = (loc + missed + false)^(1/p)``)."""

    total: float
    localisation: float
    missed: float
    false: float
    n_missed: int
    n_false: int
    pairs: tuple                 # (truth index, estimate index) assigned


def gospa(truth_m, truth_X, est_m, est_X, c: float = 2.0, p: float = 2.0) -> Gospa:
    """GOSPA (alpha = 2) between a truth set and an estimate set of ellipses."""
    nt, ne = len(truth_m), len(est_m)
    if nt == 0 or ne == 0:
        miss = c ** p / 2 * nt
        fals = c ** p / 2 * ne
        return Gospa((miss + fals) ** (1 / p), 0.0, miss, fals, nt, ne, ())
    d = gw_distance(truth_m, truth_X, est_m, est_X)
    cost = np.minimum(d, c) ** p
    rows, cols = linear_sum_assignment(cost)
    real = d[rows, cols] < c
    rows, cols = rows[real], cols[real]
    loc = float(np.sum(d[rows, cols] ** p))
    n_missed = nt - len(rows)
    n_false = ne - len(cols)
    miss = c ** p / 2 * n_missed
    fals = c ** p / 2 * n_false
    return Gospa((loc + miss + fals) ** (1 / p), loc, miss, fals, n_missed, n_false,
                 tuple(zip(rows.tolist(), cols.tolist())))


@dataclass
class TrackScore:
    """Scores over a sequence."""

    gospa_mean: float
    localisation_mean: float
    missed_mean: float
    false_mean: float
    cardinality_error: float
    id_switches: int
    fragmentations: int
    scans: int
    hidden: int = 0              # object-scans with the object wholly hidden (when known)
    hidden_kept: int = 0         # of those, the object assigned an estimate


def score_sequence(truth_seq, est_seq, c: float = 2.0, p: float = 2.0, hidden_seq=None):
    """
    Score a run.

    Parameters
    ----------
    truth_seq : list of (ids, m (n, 2), X (n, 2, 2)) per scan
    est_seq : list of (labels, m (k, 2), X (k, 2, 2)) per scan
    hidden_seq : list of (n,) bool arrays per scan, optional
        Which true objects no beam reaches (hidden by others): ``hidden`` counts them over
        the run, ``hidden_kept`` those the GOSPA assignment gives an estimate.

    Returns
    -------
    TrackScore, and the per-scan list of :class:`Gospa`.

    Notes
    -----
    An id switch is counted when a true object is assigned (by the GOSPA assignment) to a
    label other than the one it was last assigned to; a fragmentation when a true object
    assigned before is unassigned and later assigned again.
    """
    per_scan = []
    last_label, gap_open = {}, {}
    switches = frags = hidden = kept = 0
    card_err = []
    if hidden_seq is None:
        hidden_seq = [None] * len(truth_seq)
    for (tid, tm, tX), (lab, em, eX), hid in zip(truth_seq, est_seq, hidden_seq):
        g = gospa(tm, tX, em, eX, c, p)
        per_scan.append(g)
        if hid is not None:
            hid = np.asarray(hid, dtype=bool).reshape(len(tm))
            hidden += int(np.count_nonzero(hid))
            kept += sum(1 for i, _ in g.pairs if hid[i])
        card_err.append(abs(len(tm) - len(em)))
        assigned = {int(tid[i]): int(lab[j]) for i, j in g.pairs}
        for t in map(int, tid):
            if t in assigned:
                if t in last_label and last_label[t] != assigned[t]:
                    switches += 1
                if gap_open.get(t):
                    frags += 1
                gap_open[t] = False
                last_label[t] = assigned[t]
            elif t in last_label:
                gap_open[t] = True
    n = max(len(per_scan), 1)
    return TrackScore(
        gospa_mean=float(np.mean([g.total for g in per_scan])) if per_scan else 0.0,
        localisation_mean=float(np.mean([g.localisation for g in per_scan])) if per_scan else 0,
        missed_mean=float(np.mean([g.missed for g in per_scan])) if per_scan else 0.0,
        false_mean=float(np.mean([g.false for g in per_scan])) if per_scan else 0.0,
        cardinality_error=float(np.sum(card_err) / n),
        id_switches=switches, fragmentations=frags, scans=len(per_scan), hidden=hidden,
        hidden_kept=kept), per_scan
