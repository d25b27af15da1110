"""
Holding hidden tracks: confirmed objects wholly in shadow are not counted as missed.
"""

from __future__ import annotations

import numpy as np

from .algebra2 import inv2, quad_form2
from .mixture import Mixture

HOLD_OUTLINE = 1.0    # squared distance within which a cell is on a held component's outline


def held_p_d(mix: Mixture, confirmed, p_d: np.ndarray, shadowed: np.ndarray,
             comp: np.ndarray, cell: np.ndarray, cell_mean: np.ndarray, R: np.ndarray):
    """
    ``p_d`` with 0 for the components held from a miss, and which those are (a mask):
    the ``shadowed`` ones of ``confirmed`` labels that no cell lies on.

    Notes
    -----
    A component wholly in shadow gets its p_D from its interval widened by the position
    uncertainty, which reaches past the shadow as a hidden track coasts: a miss there is
    the prediction's spread, not a sign that the object is gone, and counting it scan
    after scan retired tracks the scan-shadow model is there to keep (a crowd's walkers).
    A label not yet confirmed still fades so: a spurious track beside a person would
    otherwise live on in its shadow.

    A cell lies on a component when it is one of its pairs (``comp``, ``cell``; centroids
    ``cell_mean``) and its centroid is within the component's predicted outline, the
    expected extent grown by the position covariance and the sensor noise (squared
    distance ``HOLD_OUTLINE``). There the object may be in view after all, as when a
    track lags behind its person and its own returns shadow the prediction, and the
    miss stands: held, the missed copy would keep all its weight beside the detected
    ones, and the label split (the leg_tracker demo). A cell only in the gate, beside
    the outline, is most often the occluder in front of a hidden object, and holds
    nothing back.
    """
    if confirmed is None or not shadowed.any() or not len(confirmed):
        return p_d, np.zeros(len(p_d), dtype=bool)
    held = shadowed & np.isin(mix.label, confirmed)
    rows = held[comp].nonzero()[0]                     # the held components' pairs
    if len(rows):
        c = comp[rows]
        e = cell_mean[cell[rows]] - mix.m[c, :2]
        S = mix.expected_extent(c) + mix.P[c, :2, :2] + R
        held[c[quad_form2(e, inv2(S)) <= HOLD_OUTLINE]] = False
    return np.where(held, 0.0, p_d), held


def out_of_sight(mix: Mixture, held: np.ndarray, comp: np.ndarray):
    """
    The held components of labels wholly out of sight (held, and no component of the
    label paired with a cell), as ``(rows, w_apart)``: the weight of each kept out of the
    CPHD update, one object's worth per label (``min(w, 1)`` of the label's held weight
    ``w``, shared among its held components as they hold it); None if there are none.

    Notes
    -----
    The CPHD scales every missed weight by one factor that its cardinality sets, a held
    component's too, so a hidden walker's label faded wherever the cardinality counted
    fewer objects than the labels' weights: in ``crowd20`` a walker's label went from
    2.18 to 0.27 in 14 scans, held throughout, its estimate within 0.14 m of the walker.
    No return can tell such a label anything. So one object's worth of it is taken out
    of the update, as an object the scan cannot see, the cardinality thinned by it
    first (:func:`cardinality.thin_cardinality`) and given it back after
    (:func:`cardinality.add_cardinality`). The rest of it (a label's excess over one, the
    weight gathered from both legs, say) stays in the update to fade as before, and so
    does every label with a component paired (part of it in view): taking whole weights
    out, or those of labels in part in view, kept second copies of people on the
    recordings. In PHD mode a p_D of 0 keeps the missed weight
    anyway.
    """
    rows = (held & ~np.isin(mix.label, mix.label[comp])).nonzero()[0]
    if not len(rows):
        return None
    _, group = np.unique(mix.label[rows], return_inverse=True)
    w = mix.w[rows]
    return rows, w * np.minimum(1.0, 1.0 / np.bincount(group, weights=w)[group])
