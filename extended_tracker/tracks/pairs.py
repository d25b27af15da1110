"""Leg pairs: two labels that stay together as parts of one object become one track."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..config import TrackerConfig
from ..filter.cardinality import thin_cardinality
from ..filter.mixture import Mixture
from ..filter.reduction import join_parts
from ..filter.state import FilterState
from ..sensing.legs import LEG_WIDTH
from .estimates import Estimates
from .record import NO_LABELS, SETTLED_SCANS, TrackRecord

#: the widest returns of a part in one scan (m): a leg's, as :mod:`sensing.legs` has it;
#: two people side by side at body height, half a metre apart, return mostly 0.3-0.45 m
PART_WIDTH = LEG_WIDTH


def join_pairs(filt: FilterState, record: TrackRecord, est: Estimates, cfg: TrackerConfig,
               widths: dict | None = None):
    """
    Make one track of two extracted labels that have stayed together as parts of one
    object (a walker's two legs).

    Two extracted labels are a candidate pair when one of them is part-sized (semi-major
    axis at most ``reduction.pair_semi_axis``, and the returns of its cell this scan, in
    ``widths``, at most :data:`PART_WIDTH` wide: a leg, not a person at body height, whose
    extent the filter may hold as small; a label no cell updated this scan is judged by
    its extent alone), their centres are within
    ``reduction.pair_distance`` and their velocities differ by at most
    ``reduction.pair_speed`` (one to one: pairs already forming first, then the nearest),
    and both or neither are *settled* (shown ``SETTLED_SCANS`` scans in a row without
    moving ``background.moved_distance``): a walker passing a chair, a post or a person
    standing still is no pair with it, though one of a walker's legs stands while the
    other swings. Nor are two labels both shown that long that have moved: two people
    passing each other slowly (a walker's legs pair within a few scans of a leg's birth;
    two ids of one walker that went unpaired that long stay two). A pair that has been
    one in ``reduction.pair_scans`` scans in a row is one object seen as two: their labels'
    heaviest components become one (:func:`join_parts`) under the senior label (reported
    in more scans in a row; then the smaller label) and the other label's components are
    dropped. The junior label leaves the estimates, the report record and (in
    :func:`identity.remember_shown`) the shown record. The junior of a pair still forming
    is returned too: a label never shown waits to be shown while its pair forms
    (:func:`manage.manage_tracks`), so a part born beside its object is joined before it
    is ever shown, also when the pair forms a scan or two after its birth. In CPHD mode the
    cardinality pmf loses the dropped weight (:func:`cardinality.thin_cardinality`). The
    senior's estimate this scan is as extracted; the next scan starts from the joined
    component.

    ``record``'s report must be ``est``'s (:func:`identity.record_reports`). Returns
    the filter state, the record, the estimates, the junior labels joined (ascending)
    and the juniors of the pairs still forming.

    Notes
    -----
    A scanner at leg height sees a walker as two legs. The filter often tracks each leg
    on its own: sub-partitioning then keeps them apart, since it splits a cell among the
    confident tracks that gate it (which is what keeps two people apart). A walker
    tracked as one ellipse is split again when a wide stride puts its legs in cells of
    their own: the far leg is born anew next to it. A walker's legs stay within about
    0.6 m of each other, and one swings at up to twice the walking speed while the other
    stands. Pairing leg-sized reports into one report scan by scan, without a record,
    made the report change label whenever the stride took the legs apart.
    """
    rc = cfg.reduction
    joined = forming = NO_LABELS
    pairs, runs = np.zeros((0, 2), np.int64), NO_LABELS
    if len(est) > 1:
        semi = est.axes()[0]
        i, j = np.triu_indices(len(est), 1)
        d = est.m[i, :2] - est.m[j, :2]
        dv = est.m[i, 2:] - est.m[j, 2:]
        d2 = np.sum(d * d, axis=1)
        old = record.reported_scans >= SETTLED_SCANS
        settled = record.settled_rows(cfg.background.moved_distance)
        width = np.array([(widths or {}).get(lab, 0.0) for lab in est.label.tolist()])
        part = (semi <= rc.pair_semi_axis) & (width <= PART_WIDTH)
        # a settled part pairs with a settled one only, and two old movers not at all
        ok = ((part[i] | part[j])
              & (settled[i] == settled[j]) & ~(old[i] & old[j] & ~settled[i])
              & (d2 <= rc.pair_distance ** 2)
              & (np.sum(dv * dv, axis=1) <= rc.pair_speed ** 2)).nonzero()[0]
        # each candidate's row among the last scan's pairs (-1: none); pairs already
        # forming go first, then the nearest: a leg's pair run is not broken by a
        # fragment born nearer for a scan
        before = _pair_rows(record.pairs, est.label[i[ok]], est.label[j[ok]])
        taken, chosen = set(), []
        for n in np.lexsort((d2[ok], before < 0)).tolist():
            k = ok[n]
            if i[k] not in taken and j[k] not in taken:
                taken.update((i[k], j[k]))
                chosen.append(n)
        picked = ok[chosen]
        rows = np.stack([i[picked], j[picked]], axis=1)
        pairs = est.label[rows]                        # labels ascending: smaller first
        was = before[chosen]
        runs = np.ones(len(rows), np.int64)
        runs[was >= 0] += record.pair_runs[was[was >= 0]]
        # senior first in each row: reported in more scans in a row, then the smaller label
        swap = record.reported_scans[rows[:, 1]] > record.reported_scans[rows[:, 0]]
        rows[swap] = rows[swap][:, ::-1]
        ready = runs >= rc.pair_scans
        forming = est.label[rows[~ready, 1]]
        if ready.any():
            filt, record, est, joined = _join(filt, record, est, rows[ready], cfg)
            pairs, runs = pairs[~ready], runs[~ready]
    return filt, replace(record, pairs=pairs, pair_runs=runs), est, joined, forming


def _pair_rows(pairs: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Each ``(a, b)``'s row (a < b) in ``pairs`` (the last scan's), or -1."""
    rows = np.full(len(a), -1, dtype=np.int64)
    if len(pairs) and len(a):
        hit = (pairs[None, :, 0] == a[:, None]) & (pairs[None, :, 1] == b[:, None])
        found = hit.any(axis=1)
        rows[found] = hit[found].argmax(axis=1)
    return rows


def _join(filt: FilterState, record: TrackRecord, est: Estimates, rows: np.ndarray,
          cfg: TrackerConfig):
    """Join the labels of each pair of ``est`` rows (see :func:`join_pairs`)."""
    mix = filt.mixture
    order, is_head, _ = mix.by_label()
    labels, _, weight = mix.per_label()
    heads = order[is_head]
    drop = np.zeros(len(mix), dtype=bool)
    joined, junior_rows, removed = [], [], 0.0
    for a, b in rows.tolist():                         # the senior first
        at = labels.searchsorted(est.label[[a, b]])
        w = weight[at]
        joined.append(join_parts(mix, heads[at], w, int(est.label[a])))
        drop |= (mix.label == est.label[a]) | (mix.label == est.label[b])
        junior_rows.append(b)
        removed += float(w.sum() - w.max())
    log_card = filt.log_card
    if cfg.model.mode == 'cphd':
        log_card = thin_cardinality(log_card, removed)
    keep = np.ones(len(est), dtype=bool)
    keep[junior_rows] = False
    filt = replace(filt, mixture=Mixture.concat([mix.take(~drop)] + joined), log_card=log_card)
    record = replace(record, reported=record.reported[keep],
                     reported_scans=record.reported_scans[keep],
                     reported_origin=record.reported_origin[keep],
                     reported_travel=record.reported_travel[keep],
                     reported_size=record.reported_size[keep],
                     reported_hits=record.reported_hits[keep])
    return filt, record, est.take(keep), np.sort(est.label[~keep])
