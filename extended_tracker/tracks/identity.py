"""
The ids a user sees: what happens to the filter's labels between extraction and report.

A label is reported once confirmed (:meth:`record.TrackRecord.confirmed_rows`); after
that its id must mean one object. A label that could not have got where it is gets a
fresh id (:func:`relabel_jumps`); a lost id passes to a young object where the lost one
would be (:func:`hand_over`); the report record counts scans, returns and travel
(:func:`record_reports`); where and when each id was last shown is remembered
(:func:`remember_shown`). :func:`manage.manage_tracks` calls them, with the leg pairs
(:mod:`tracks.pairs`) and the grouped contour pieces (:mod:`tracks.grouping`).
"""

from __future__ import annotations

from dataclasses import replace
import math

import numpy as np

from ..config import TrackerConfig
from ..filter.state import FilterState
from .estimates import Estimates
from .record import find_sorted, NO_LABELS, TrackRecord


def relabel_jumps(record: TrackRecord, filt: FilterState, est: Estimates,
                  cfg: TrackerConfig, dt: float):
    """
    Give a new label to each extracted label that could not have got where it is.

    A label last shown at ``p`` ``t`` seconds ago and now extracted at ``q`` moved at
    least ``|q - p| / t``. Farther than ``extraction.max_speed * t +
    extraction.jump_slack`` it is not the object that was shown: a track that coasted
    unseen while its position uncertainty grew to metres has taken the returns of a
    newcomer (the CV model's white acceleration lets it; a walker does not run at
    6 m/s). Likewise when ``q`` is farther than ``extraction.max_accel * t^2 / 2 +
    jump_slack`` from ``p + v t``, ``v`` the velocity it was shown with: an object at
    rest does not cover 3 m in 0.4 s. The estimate stays where the filter put it, under
    a fresh label that must be confirmed like any new object, and the old id is not
    reused.

    Returns the filter state (mixture relabelled, ``next_label`` advanced), the estimates (still
    in ascending label order) and the number of labels changed.

    Notes
    -----
    Seen on the leg_tracker positive_1 recording: ids that jumped 4.2 m in 0.4 s and
    8.6 m in 1.2 s (since last shown) onto people who had just entered. On the
    obstacle_detector recording, tracks on static posts jumped 3-4 m to another post
    within the default 15 m/s.
    """
    if not len(record.shown) or not len(est):
        return filt, est, 0
    ex = cfg.extraction
    # a handful of labels: Python floats, the same operations as arrays would take
    index = {lab: i for i, lab in enumerate(record.shown.tolist())}
    pos, vel = record.shown_pos.tolist(), record.shown_vel.tolist()
    ago = record.shown_elapsed.tolist()
    jumped = []
    for row, (lab, m) in enumerate(zip(est.label.tolist(), est.m.tolist())):
        i = index.get(lab)
        if i is None:
            continue
        t = ago[i] + dt
        dx, dy = m[0] - pos[i][0], m[1] - pos[i][1]
        if math.sqrt(dx * dx + dy * dy) > _speed_reach(ex, t):
            jumped.append(row)
        elif ex.max_accel > 0:
            dx -= vel[i][0] * t                      # from where its velocity carried it
            dy -= vel[i][1] * t
            if math.sqrt(dx * dx + dy * dy) > 0.5 * ex.max_accel * t * t + ex.jump_slack:
                jumped.append(row)
    if not jumped:
        return filt, est, 0
    jumped = np.array(jumped, dtype=np.int64)
    bad = est.label[jumped]
    fresh = filt.next_label + np.arange(len(bad))
    mix = filt.mixture
    label = mix.label.copy()
    at, hit = find_sorted(bad, label)                   # est.label is ascending
    label[hit] = fresh[at[hit]]
    est_label = est.label.copy()
    est_label[jumped] = fresh
    # the fresh labels are the largest: move them to the end, so the estimates stay in
    # ascending label order as extract gives them (the shown record searches them)
    order = est_label.argsort(kind='stable')
    return (replace(filt, mixture=replace(mix, label=label),
                   next_label=filt.next_label + len(bad)),
            replace(est, label=est_label).take(order), len(bad))


def _norm(d: np.ndarray, axis: int) -> np.ndarray:
    """Euclidean length along ``axis``."""
    return np.sqrt(np.sum(d * d, axis=axis))


def _speed_reach(ex, t):
    """How far an id may be from where it was shown ``t`` seconds ago under the speed
    limit: ``extraction.max_speed * t + extraction.jump_slack``."""
    return ex.max_speed * t + ex.jump_slack


def hand_over(record: TrackRecord, filt: FilterState, est: Estimates, cfg: TrackerConfig,
              dt: float, first_label: int):
    """
    Give a lost id to a young object that appeared where the lost one would be.

    A label shown less than ``extraction.handover_time`` ago that is not extracted now is
    lost. A label created less than ``handover_time`` ago and extracted now is young. A
    young label within ``extraction.handover_distance`` of a lost label's last shown
    position, carried on at its last shown velocity, takes the lost label (one to one;
    the ids of lost movers first, then of lost settled labels, each nearest pairs first),
    unless the speed limit of :func:`relabel_jumps` would call the move a jump, or the
    lost label is the newer of the two: an id passes only to a label created after it.
    Established labels never take another's id, so two tracked objects that pass each
    other keep theirs.

    In the mixture the two labels swap: the young object's components carry the old id
    on, the lost label's fading components carry the young one. The young label's report
    count passes to the old id when the old id was not extracted in the last scan, so a
    handed-over id is confirmed as the young one would have been.

    ``first_label`` is the label counter at the start of this scan.

    Returns the filter state, the estimates (ascending labels), the record to continue
    from (the young labels' report counts renamed) and the number of handovers.

    Notes
    -----
    Seen at leg height (the leg_tracker demo): a walker tracked on one leg while the other
    is hidden; the other leg steps out 0.3-0.5 m ahead, is split off under a new label,
    and the first leg's track fades when that leg is hidden in turn. Without a handover
    the walker changes id at every such step. On the Freiburg recording two young labels
    on one walker, just after the background warm-up, traded ids every scan for 26 scans
    (the one extracted took the id of the other, shown the scan before) until both were
    older than the window; an id passing only to a newer label ends that.

    Movers first: on the MiR recording a walker came within 0.7 m of an object tracked
    where it stood since start-up. One cell held both, a new label took it, and both
    tracks were missed. The new label stood nearer the object's last shown position, took
    its id and carried it away with the walker, whose own id ended there. A settled label
    (:meth:`record.TrackRecord.settled_rows`, reported in the last scan) that is lost is
    most often still where it was, its returns taken by a neighbour for a scan. A mover
    lost beside a new label has gone into it.
    """
    window = cfg.extraction.handover_time
    if window <= 0 or not len(record.shown) or not len(est):
        return filt, est, record, 0
    extracted = set(est.label.tolist())
    lost = [i for i, (lab, ago) in enumerate(zip(record.shown.tolist(),
                                                 record.shown_elapsed.tolist()))
            if ago + dt <= window and lab not in extracted]
    if not lost:
        return filt, est, record, 0
    # labels created this scan are >= first_label, earlier ones in the window >= the
    # counter at the window's start
    first_young = next((lab for ago, lab in record.label_clock if ago + dt <= window),
                       first_label)
    young = (est.label >= first_young).nonzero()[0]
    if not len(young):
        return filt, est, record, 0
    ex = cfg.extraction
    lost = np.array(lost)
    elapsed = record.shown_elapsed[lost] + dt
    pos, last = est.m[young, None, :2], record.shown_pos[None, lost]
    d = pos - (last + record.shown_vel[None, lost] * elapsed[None, :, None])
    dist = _norm(d, 2)                                 # (young, lost)
    # and never farther than the speed limit lets an id move (see relabel_jumps)
    d = pos - last
    reach = _speed_reach(ex, elapsed)
    near = ((dist <= ex.handover_distance)
            & (_norm(d, 2) <= reach[None, :])
            & (est.label[young][:, None] > record.shown[lost][None, :])).nonzero()
    if not len(near[0]):
        return filt, est, record, 0
    order = np.lexsort((dist[near], _settled(record, lost, cfg)[near[1]]))
    taken_y, taken_l, pairs = set(), set(), []
    for yi, li in zip(near[0][order].tolist(), near[1][order].tolist()):
        if yi not in taken_y and li not in taken_l:
            taken_y.add(yi)
            taken_l.add(li)
            pairs.append((int(est.label[young[yi]]), int(record.shown[lost[li]])))
    mix = filt.mixture
    label = mix.label.copy()
    est_label = est.label.copy()
    rec = record.reported.copy()
    for y, a in pairs:
        is_y, is_a = mix.label == y, mix.label == a
        label[is_y], label[is_a] = a, y
        est_label[est.label == y] = a
        if not (rec == a).any():
            rec[rec == y] = a
    order = est_label.argsort(kind='stable')
    return (replace(filt, mixture=replace(mix, label=label)),
            replace(est, label=est_label).take(order), replace(record, reported=rec), len(pairs))


def _settled(record: TrackRecord, rows: np.ndarray, cfg: TrackerConfig) -> np.ndarray:
    """Whether each of the ``shown`` labels at ``rows`` is settled as the last report
    left it; one not in that report counts as a mover."""
    if not len(record.reported):
        return np.zeros(len(rows), dtype=bool)
    at, found = find_sorted(record.reported, record.shown[rows])
    return found & record.settled_rows(cfg.background.moved_distance)[at]


def record_reports(record: TrackRecord, est: Estimates) -> TrackRecord:
    """Carry per-label report counts, scans with returns, first positions and distances
    travelled."""
    has = est.num_detections > 0
    if len(est) == len(record.reported) and (est.label == record.reported).all():
        # the labels of the last report again (most scans): row for row, nothing new
        travel = _norm(est.m[:, :2] - record.reported_origin, 1)
        # only where returns placed it: a coasting label drifts with its predicted velocity
        travel = np.maximum(np.where(has, travel, 0.0), record.reported_travel)
        return replace(record, reported=est.label.copy(),
                      reported_scans=record.reported_scans + 1,
                      reported_origin=record.reported_origin, reported_travel=travel,
                      reported_size=record.reported_size, reported_hits=record.reported_hits + has)
    index = {int(lab): i for i, lab in enumerate(record.reported.tolist())}
    # each label's row in the last report (-1: reported for the first time)
    prev = np.array([index.get(lab, -1) for lab in est.label.tolist()], dtype=np.int64)
    again = prev >= 0
    i = prev[again]
    scans = np.ones(len(est), dtype=np.int64)
    scans[again] = record.reported_scans[i] + 1
    origin = est.m[:, :2].copy()
    origin[again] = record.reported_origin[i]
    size = np.empty(len(est))
    size[again] = record.reported_size[i]
    if len(i) < len(est):                          # the semi-major axis of the new ones
        size[~again] = est.axes()[0][~again]
    d = est.m[:, :2] - origin
    travel = _norm(d, 1)
    # only where returns placed it: a coasting label drifts with its predicted velocity
    travel[~has] = 0.0
    travel[again] = np.maximum(travel[again], record.reported_travel[i])
    hits = has.astype(np.int64)
    hits[again] += record.reported_hits[i]
    return replace(record, reported=est.label.copy(), reported_scans=scans, reported_origin=origin,
                  reported_travel=travel, reported_size=size, reported_hits=hits)


def remember_shown(record: TrackRecord, filt: FilterState, shown: Estimates, dt: float,
                   first_label: int, handover_time: float = 0.0,
                   joined=NO_LABELS) -> TrackRecord:
    """
    Where, at what velocity and how long ago each label was last shown: labels still in
    the mixture, and those shown less than ``handover_time`` ago (they may be handed
    over, see :func:`hand_over`), but not the ``joined`` labels (ascending): they are
    part of another object now, not lost (:func:`join_pairs`). Also the label counter
    of the last ``handover_time`` seconds (``first_label``: this scan's start).
    """
    # a handful of labels: sets and lists
    alive = set(filt.mixture.per_label()[0].tolist())   # cached by extract
    now = set(shown.label.tolist())
    gone = set(joined.tolist())
    keep = [i for i, (lab, ago) in enumerate(zip(record.shown.tolist(),
                                                 record.shown_elapsed.tolist()))
            if (lab in alive or ago + dt <= handover_time) and lab not in now
            and lab not in gone]
    clock = tuple((ago + dt, lab) for ago, lab in record.label_clock if ago + dt <= handover_time)
    clock += ((0.0, first_label),)
    if not keep and (shown.label[1:] > shown.label[:-1]).all():
        # every label of the record is shown again or gone (most scans): the record is this
        # scan's, its labels ascending already (as the estimates come)
        return replace(record, shown=shown.label.copy(), shown_pos=shown.m[:, :2].copy(),
                      shown_vel=shown.m[:, 2:].copy(), shown_elapsed=np.zeros(len(shown)),
                      label_clock=clock)
    keep = np.array(keep, dtype=np.int64)
    label = np.concatenate([record.shown[keep], shown.label])
    pos = np.concatenate([record.shown_pos[keep], shown.m[:, :2]])
    vel = np.concatenate([record.shown_vel[keep], shown.m[:, 2:]])
    elapsed = np.concatenate([record.shown_elapsed[keep] + dt, np.zeros(len(shown))])
    order = label.argsort(kind='stable')
    return replace(record, shown=label[order], shown_pos=pos[order],
                  shown_vel=vel[order], shown_elapsed=elapsed[order], label_clock=clock)
