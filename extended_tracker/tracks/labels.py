"""
Labels of the posterior: fuse labels that track one object, split a label whose
components ended far apart.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..filter.algebra2 import inv2
from ..filter.mixture import Mixture, weight_key
from .record import find_sorted


def _spread_inv(mix: Mixture, idx) -> np.ndarray:
    """Inverse of position covariance plus expected extent of components ``idx``: the
    metric in which a label's members are near their head (splitting, fusion)."""
    return inv2(mix.P[idx][:, :2, :2] + mix.expected_extent(idx))


def fuse_duplicate_labels(mix: Mixture, merge_distance: float, fuse_weight: float,
                           reported=None, reported_scans=None):
    """
    Give one label to labels that track the same object.

    Two labels whose heaviest components lie within the merge distance of each other
    (both ways, in the metric of :func:`split_labels`: position covariance plus extent)
    and whose weights sum to at most ``fuse_weight`` are one object seen twice. With the
    default merge distance the heads are then closer than about twice the extent's
    spread, where two objects would overlap; and two *tracked* objects passing close
    (crossing, one behind the other) carry about one unit of weight each, so they stay
    apart.

    The label that stays is the senior one: reported in more consecutive scans
    (``reported`` labels with their ``reported_scans``), then the heavier, then the older
    (smaller) label;
    the other's components join it. The id a user sees is kept, whichever hypothesis is
    heavier at that moment.

    Returns the mixture and the number of labels fused away.

    Notes
    -----
    Seen on real recordings: one object born from two cells with no return in common
    (the halves of a sub-partition) got two labels; both then followed the whole object,
    splitting its weight (0.36 and 0.74), and a neighbour's label took it over when one
    of them faded. On the leg_tracker demo a walker's fading track and a fresh birth on
    the same legs were fused under the birth's label while the heavier label absorbed:
    the walker changed id. Seniority keeps it. Among labels not reported, the older had
    stayed: a light label left coasting on a static spot that flickers (shown there
    seconds before) got a detected component on a newcomer's returns metres away, and
    the newcomer took its id (2.5 m on obstacle_detector, 7.4 m on positive_1). The
    heavier, the birth that explains the returns, now stays.
    """
    if not len(mix) or fuse_weight <= 0:
        return mix, 0
    order, is_head, group = mix.by_label()
    if not group[-1]:
        return mix, 0                                  # a single label
    labels, _, weight = mix.per_label()
    # only labels light enough to pair with the lightest other one can take part (the two
    # lightest by a Python sort: a handful of labels)
    wl = weight.tolist()
    low, second = sorted(wl)[:2]
    cand = [i for i, x in enumerate(wl) if x + (second if x == low else low) <= fuse_weight]
    if len(cand) < 2:
        return mix, 0
    cand = np.array(cand, dtype=np.int64)
    heads = order[is_head][cand]
    c = mix.m[heads][:, :2]
    inv_spread = _spread_inv(mix, heads)
    e = c[None, :, :] - c[:, None, :]                  # e[i, j] = c_j - c_i
    d2 = np.einsum('ijk,ikl,ijl->ij', e, inv_spread, e)    # in head i's metric
    close = (np.maximum(d2, d2.T) <= merge_distance)
    np.fill_diagonal(close, False)
    if not close.any():
        return mix, 0
    scans = np.zeros(len(cand), dtype=np.int64)
    if reported is not None and len(reported):
        at, ok = find_sorted(labels, reported)
        full = np.zeros(len(labels), dtype=np.int64)
        full[at[ok]] = reported_scans[ok]
        scans = full[cand]
    # seniority: most scans reported, then the heavier, then the older label (cand is in
    # label order)
    w = weight[cand]
    senior = np.lexsort((np.arange(len(cand)), -weight_key(w), -scans))
    rank = np.empty(len(cand), dtype=np.int64)
    rank[senior] = np.arange(len(cand))
    into = np.arange(len(cand))
    total = w.copy()
    for i in senior.tolist():
        if into[i] != i:
            continue                                   # joined a more senior label
        for j in close[i].nonzero()[0].tolist():
            if into[j] == j and rank[j] > rank[i] and total[i] + total[j] <= fuse_weight:
                into[j] = i
                total[i] += total[j]
    fused = int(np.count_nonzero(into != np.arange(len(cand))))
    if not fused:
        return mix, 0
    target = np.arange(len(weight))
    target[cand] = cand[into]
    label = mix.label.copy()
    label[order] = labels[target[group]]
    return replace(mix, label=label), fused


def split_labels(mix: Mixture, split_weight: float, merge_distance: float, next_label: int):
    """
    Resolve labels whose components ended up far apart after merging.

    A far component (outside the merge distance of its label's heaviest) that is heavy
    becomes a new object with a fresh label (two pedestrians side by side separating); a
    light one is dropped: one object is not in two places, and keeping it makes the
    label's reported position jump between the two.
    """
    if not len(mix):
        return mix, next_label
    order, is_head, group = mix.by_label()
    if is_head.all():
        return mix, next_label                         # one component a label (most scans)
    heads = order[is_head]
    pos = mix.m[:, :2]
    e = pos[order] - pos[heads[group]]
    d2 = np.einsum('ki,kij,kj->k', e, _spread_inv(mix, heads)[group], e)
    far = np.zeros(len(mix), dtype=bool)
    far[order] = (d2 > merge_distance) & ~is_head
    if not far.any():
        return mix, next_label
    heavy = far & (mix.w >= split_weight)
    label = mix.label.copy()
    # fresh labels in order of weight, as the objects they stand for are found
    new = heavy.nonzero()[0]
    new = new[(-weight_key(mix.w[new])).argsort(kind='stable')]
    label[new] = next_label + np.arange(len(new))
    keep = ~(far & ~heavy)
    return replace(mix, label=label).take(keep), next_label + len(new)
