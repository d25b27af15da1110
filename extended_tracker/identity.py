"""
The ids a user sees: what happens to the filter's labels between extraction and report.

A label is reported once confirmed (:meth:`FilterState.confirmed_rows`); after that its
id must mean one object. A label that could not have got where it is gets a fresh id
(:func:`relabel_jumps`); a lost id passes to a young object where the lost one would be
(:func:`hand_over`); the report record counts scans, returns and travel
(:func:`record_reports`); two labels that stay together as parts of one object become one
track (:func:`join_pairs`); where and when each id was last shown is remembered
(:func:`remember_shown`); the thin pieces of one contour are reported as one object
(:func:`group_segments`). :func:`tracker.update_state` calls them in that order.
"""

from __future__ import annotations

from dataclasses import replace
import math

import numpy as np

from .config import TrackerConfig
from .cphd import thin_cardinality
from .ggiw import Mixture
from .partition import find_root, union_min
from .reduction import join_parts
from .state import Estimates, FilterState, find_sorted, NO_LABELS

# a thin contour piece (see group_segments): semi-minor axis at most this, semi-major at least.
# A car's end piece often holds a stretch of its side by the corner as well, which
# takes its semi-minor axis to 0.16-0.24 m (mixed_traffic)
SEGMENT_MAX_SEMI_MINOR = 0.25        # m
SEGMENT_MIN_SEMI_MAJOR = 0.5         # m
# a piece moving faster than people walk is a vehicle's, and counts from this length on: a
# nearer object's shadow or a gap in sparse returns cuts a bicycle's side or a car's end
# into pieces of 0.4-0.5 m, while a person's track (a leg pair at leg height, seen as an
# arc) reaches 0.4-0.5 m too, standing or walking (MiR's circling walkers)
SEGMENT_FAST_MIN_SEMI_MAJOR = 0.4    # m
SEGMENT_FAST_SPEED = 2.5             # m/s


def relabel_jumps(old: FilterState, new: FilterState, est: Estimates, cfg: TrackerConfig):
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

    Returns the state (mixture relabelled, ``next_label`` advanced), the estimates (still
    in ascending label order) and the number of labels changed.

    Notes
    -----
    Seen on the leg_tracker positive_1 recording: ids that jumped 4.2 m in 0.4 s and
    8.6 m in 1.2 s (since last shown) onto people who had just entered. On the
    obstacle_detector recording, tracks on static posts jumped 3-4 m to another post
    within the default 15 m/s.
    """
    if not len(old.shown) or not len(est):
        return new, est, 0
    ex = cfg.extraction
    # a handful of labels: Python floats, the same operations as arrays would take
    index = {lab: i for i, lab in enumerate(old.shown.tolist())}
    pos, vel, ago = old.shown_pos.tolist(), old.shown_vel.tolist(), old.shown_elapsed.tolist()
    dt = new.dt
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
        return new, est, 0
    jumped = np.array(jumped, dtype=np.int64)
    bad = est.label[jumped]
    fresh = new.next_label + np.arange(len(bad))
    mix = new.mixture
    label = mix.label.copy()
    at, hit = find_sorted(bad, label)                   # est.label is ascending
    label[hit] = fresh[at[hit]]
    est_label = est.label.copy()
    est_label[jumped] = fresh
    # the fresh labels are the largest: move them to the end, so the estimates stay in
    # ascending label order as extract gives them (the shown record searches them)
    order = est_label.argsort(kind='stable')
    return (replace(new, mixture=replace(mix, label=label),
                   next_label=new.next_label + len(bad)),
            replace(est, label=est_label).take(order), len(bad))


def _norm(d: np.ndarray, axis: int) -> np.ndarray:
    """Euclidean length along ``axis``."""
    return np.sqrt(np.sum(d * d, axis=axis))


def _speed_reach(ex, t):
    """How far an id may be from where it was shown ``t`` seconds ago under the speed
    limit: ``extraction.max_speed * t + extraction.jump_slack``."""
    return ex.max_speed * t + ex.jump_slack


def hand_over(old: FilterState, new: FilterState, est: Estimates, cfg: TrackerConfig):
    """
    Give a lost id to a young object that appeared where the lost one would be.

    A label shown less than ``extraction.handover_time`` ago that is not extracted now is
    lost. A label created less than ``handover_time`` ago and extracted now is young. A
    young label within ``extraction.handover_distance`` of a lost label's last shown
    position, carried on at its last shown velocity, takes the lost label (nearest pairs
    first, one to one), unless the speed limit of :func:`relabel_jumps` would call the
    move a jump, or the lost label is the newer of the two: an id passes only to a label
    created after it. Established labels never take another's id, so two tracked objects
    that pass each other keep theirs.

    In the mixture the two labels swap: the young object's components carry the old id
    on, the lost label's fading components carry the young one. The young label's report
    count passes to the old id when the old id was not extracted in the last scan, so a
    handed-over id is confirmed as the young one would have been.

    Returns the state, the estimates (ascending labels), the report record to continue
    from (``old`` with the young labels' counts renamed) and the number of handovers.

    Notes
    -----
    Seen at leg height (the leg_tracker demo): a walker tracked on one leg while the other
    is hidden; the other leg steps out 0.3-0.5 m ahead, is split off under a new label,
    and the first leg's track fades when that leg is hidden in turn. Without a handover
    the walker changes id at every such step. On the Freiburg recording two young labels
    on one walker, just after the background warm-up, traded ids every scan for 26 scans
    (the one extracted took the id of the other, shown the scan before) until both were
    older than the window; an id passing only to a newer label ends that.
    """
    window = cfg.extraction.handover_time
    if window <= 0 or not len(old.shown) or not len(est):
        return new, est, old, 0
    dt = new.dt
    extracted = set(est.label.tolist())
    lost = [i for i, (lab, ago) in enumerate(zip(old.shown.tolist(),
                                                 old.shown_elapsed.tolist()))
            if ago + dt <= window and lab not in extracted]
    if not lost:
        return new, est, old, 0
    # labels created this scan are >= old.next_label, earlier ones in the window >= the
    # counter at the window's start
    first_young = next((lab for ago, lab in old.label_clock if ago + dt <= window),
                       old.next_label)
    young = (est.label >= first_young).nonzero()[0]
    if not len(young):
        return new, est, old, 0
    ex = cfg.extraction
    lost = np.array(lost)
    elapsed = old.shown_elapsed[lost] + dt
    pos, last = est.m[young, None, :2], old.shown_pos[None, lost]
    d = pos - (last + old.shown_vel[None, lost] * elapsed[None, :, None])
    dist = _norm(d, 2)                                 # (young, lost)
    # and never farther than the speed limit lets an id move (see relabel_jumps)
    d = pos - last
    reach = _speed_reach(ex, elapsed)
    near = ((dist <= ex.handover_distance)
            & (_norm(d, 2) <= reach[None, :])
            & (est.label[young][:, None] > old.shown[lost][None, :])).nonzero()
    if not len(near[0]):
        return new, est, old, 0
    order = dist[near].argsort(kind='stable')
    taken_y, taken_l, pairs = set(), set(), []
    for yi, li in zip(near[0][order].tolist(), near[1][order].tolist()):
        if yi not in taken_y and li not in taken_l:
            taken_y.add(yi)
            taken_l.add(li)
            pairs.append((int(est.label[young[yi]]), int(old.shown[lost[li]])))
    mix = new.mixture
    label = mix.label.copy()
    est_label = est.label.copy()
    rec = old.reported.copy()
    for y, a in pairs:
        is_y, is_a = mix.label == y, mix.label == a
        label[is_y], label[is_a] = a, y
        est_label[est.label == y] = a
        if not np.any(rec == a):
            rec[rec == y] = a
    order = est_label.argsort(kind='stable')
    return (replace(new, mixture=replace(mix, label=label)),
            replace(est, label=est_label).take(order), replace(old, reported=rec), len(pairs))


def record_reports(old: FilterState, new: FilterState, est: Estimates) -> FilterState:
    """Carry per-label report counts, scans with returns, first positions and distances
    travelled."""
    has = est.num_detections > 0
    if len(est) == len(old.reported) and np.all(est.label == old.reported):
        # the labels of the last report again (most scans): row for row, nothing new
        travel = _norm(est.m[:, :2] - old.reported_origin, 1)
        # only where returns placed it: a coasting label drifts with its predicted velocity
        travel = np.maximum(np.where(has, travel, 0.0), old.reported_travel)
        return replace(new, reported=est.label.copy(),
                      reported_scans=old.reported_scans + 1,
                      reported_origin=old.reported_origin, reported_travel=travel,
                      reported_size=old.reported_size, reported_hits=old.reported_hits + has)
    index = {int(lab): i for i, lab in enumerate(old.reported.tolist())}
    # each label's row in the last report (-1: reported for the first time)
    prev = np.array([index.get(lab, -1) for lab in est.label.tolist()], dtype=np.int64)
    again = prev >= 0
    i = prev[again]
    scans = np.ones(len(est), dtype=np.int64)
    scans[again] = old.reported_scans[i] + 1
    origin = est.m[:, :2].copy()
    origin[again] = old.reported_origin[i]
    size = np.empty(len(est))
    size[again] = old.reported_size[i]
    if len(i) < len(est):                          # the semi-major axis of the new ones
        size[~again] = est.axes()[0][~again]
    d = est.m[:, :2] - origin
    travel = _norm(d, 1)
    # only where returns placed it: a coasting label drifts with its predicted velocity
    travel[~has] = 0.0
    travel[again] = np.maximum(travel[again], old.reported_travel[i])
    hits = has.astype(np.int64)
    hits[again] += old.reported_hits[i]
    return replace(new, reported=est.label.copy(), reported_scans=scans, reported_origin=origin,
                  reported_travel=travel, reported_size=size, reported_hits=hits)


def join_pairs(state: FilterState, est: Estimates, cfg: TrackerConfig):
    """
    Make one track of two extracted labels that have stayed together as parts of one
    object (a walker's two legs).

    Two extracted labels are a candidate pair when one of them is part-sized (semi-major
    axis at most ``reduction.pair_semi_axis``), their centres are within
    ``reduction.pair_distance`` and their velocities differ by at most
    ``reduction.pair_speed`` (nearest pairs first, one to one). A pair that has been one
    in ``reduction.pair_scans`` scans in a row is one object seen as two: their labels'
    heaviest components become one (:func:`join_parts`) under the senior label (reported
    in more scans in a row; then the smaller label) and the other label's components are
    dropped. The junior label leaves the estimates, the report record and (in
    :func:`remember_shown`) the shown record. The junior of a pair still forming is
    returned too: a label never shown waits to be shown while its pair forms
    (:func:`update_state`), so a part born beside its object is joined before it is ever
    shown, also when the pair forms a scan or two after its birth. In CPHD mode the
    cardinality pmf loses the dropped weight (:func:`cphd.thin_cardinality`). The
    senior's estimate this scan is as extracted; the next scan starts from the joined
    component.

    ``state``'s report record must be ``est``'s (:func:`record_reports`). Returns the
    state, the estimates, the junior labels joined (ascending) and the juniors of the
    pairs still forming.

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
        ok = ((np.minimum(semi[i], semi[j]) <= rc.pair_semi_axis)
              & (d2 <= rc.pair_distance ** 2)
              & (np.sum(dv * dv, axis=1) <= rc.pair_speed ** 2)).nonzero()[0]
        taken, rows = set(), []
        for k in ok[d2[ok].argsort(kind='stable')].tolist():
            if i[k] not in taken and j[k] not in taken:
                taken.update((i[k], j[k]))
                rows.append((i[k], j[k]))
        rows = np.array(rows, dtype=np.int64).reshape(-1, 2)
        pairs = est.label[rows]                        # labels ascending: smaller first
        runs = np.ones(len(rows), np.int64)
        for n, (a, b) in enumerate(pairs.tolist()):
            was = ((state.pairs[:, 0] == a) & (state.pairs[:, 1] == b)).nonzero()[0]
            if len(was):
                runs[n] += state.pair_runs[was[0]]
        # senior first in each row: reported in more scans in a row, then the smaller label
        swap = state.reported_scans[rows[:, 1]] > state.reported_scans[rows[:, 0]]
        rows[swap] = rows[swap][:, ::-1]
        ready = runs >= rc.pair_scans
        forming = est.label[rows[~ready, 1]]
        if np.any(ready):
            state, est, joined = _join(state, est, rows[ready], cfg)
            pairs, runs = pairs[~ready], runs[~ready]
    return replace(state, pairs=pairs, pair_runs=runs), est, joined, forming


def _join(state: FilterState, est: Estimates, rows: np.ndarray, cfg: TrackerConfig):
    """Join the labels of each pair of ``est`` rows (see :func:`join_pairs`)."""
    mix = state.mixture
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
    log_card = state.log_card
    if cfg.model.mode == 'cphd':
        log_card = thin_cardinality(log_card, removed)
    keep = np.ones(len(est), dtype=bool)
    keep[junior_rows] = False
    state = replace(state, mixture=Mixture.concat([mix.take(~drop)] + joined),
                   log_card=log_card, reported=state.reported[keep],
                   reported_scans=state.reported_scans[keep],
                   reported_origin=state.reported_origin[keep],
                   reported_travel=state.reported_travel[keep],
                   reported_size=state.reported_size[keep],
                   reported_hits=state.reported_hits[keep])
    return state, est.take(keep), np.sort(est.label[~keep])


def remember_shown(old: FilterState, new: FilterState, shown: Estimates,
                   handover_time: float = 0.0, joined=NO_LABELS) -> FilterState:
    """
    Where, at what velocity and how long ago each label was last shown: labels still in
    the mixture, and those shown less than ``handover_time`` ago (they may be handed
    over, see :func:`hand_over`), but not the ``joined`` labels (ascending): they are
    part of another object now, not lost (:func:`join_pairs`). Also the label counter
    of the last ``handover_time`` seconds.
    """
    dt = new.dt
    # a handful of labels: sets and lists
    alive = set(new.mixture.per_label()[0].tolist())   # cached by extract
    now = set(shown.label.tolist())
    gone = set(joined.tolist())
    keep = [i for i, (lab, ago) in enumerate(zip(old.shown.tolist(),
                                                 old.shown_elapsed.tolist()))
            if (lab in alive or ago + dt <= handover_time) and lab not in now
            and lab not in gone]
    clock = tuple((ago + dt, lab) for ago, lab in old.label_clock if ago + dt <= handover_time)
    clock += ((0.0, old.next_label),)
    if not keep and np.all(shown.label[1:] > shown.label[:-1]):
        # every label of the record is shown again or gone (most scans): the record is this
        # scan's, its labels ascending already (as the estimates come)
        return replace(new, shown=shown.label.copy(), shown_pos=shown.m[:, :2].copy(),
                      shown_vel=shown.m[:, 2:].copy(), shown_elapsed=np.zeros(len(shown)),
                      label_clock=clock)
    keep = np.array(keep, dtype=np.int64)
    label = np.concatenate([old.shown[keep], shown.label])
    pos = np.concatenate([old.shown_pos[keep], shown.m[:, :2]])
    vel = np.concatenate([old.shown_vel[keep], shown.m[:, 2:]])
    elapsed = np.concatenate([old.shown_elapsed[keep] + dt, np.zeros(len(shown))])
    order = label.argsort(kind='stable')
    return replace(new, shown=label[order], shown_pos=pos[order],
                  shown_vel=vel[order], shown_elapsed=elapsed[order], label_clock=clock)


def group_segments(est: Estimates, seniority: np.ndarray, gap: float, speed: float):
    """
    Report the thin pieces of one object's contour as that object.

    A laser sees a car across a corner as an L: its long side and its end. Two thin
    ellipses explain those returns far better than one ellipse over the car does (the
    model spreads detections over the extent, the scanner sees the contour), so the filter
    tracks two thin objects. Pieces at most ``SEGMENT_MAX_SEMI_MINOR`` thick and at least
    ``SEGMENT_MIN_SEMI_MAJOR`` long, one of which has an end within ``gap`` of the other
    piece (of its segment, not only of its ends), and whose velocities differ by at most
    ``speed`` are reported as one object (a piece moving at ``SEGMENT_FAST_SPEED`` or
    more counts from ``SEGMENT_FAST_MIN_SEMI_MAJOR``): the rectangle
    around them in the frame of the longest piece (its extent the rectangle's second
    moments), moving at their rate-weighted velocity, under the label of the longest
    piece (between pieces of one length, the most ``seniority``, reported scans in a row,
    then the smaller label), its position covariance that piece's. Existence and
    visibility are the pieces' largest, rate and detections their sums.

    The longest piece, not the most senior, because ungrouped it is the piece nearest the
    object: when the grouping comes and goes from scan to scan, the report stays on one
    label. The most senior piece as the head raised ``mixed_traffic``'s id switches from
    4/3/3/3 to 6/3/11/5 (the results table's four variants, when this was written).

    Returns the estimates (ascending labels) and the number of pieces grouped into
    another's report.

    Notes
    -----
    The side's estimate reaches past the car's ends or short of them: its centre lags a
    moving car and its length is a second moment. In ``mixed_traffic`` the end piece's
    end touched the side 1 m in from the side's estimated end, and with the ends alone
    compared the car was two reports there.
    """
    k = len(est)
    if gap <= 0 or k < 2:
        return est, 0
    # the semi-major axis squared is at most the trace: people are ruled out at once
    X = est.X
    long_ = (X[:, 0, 0] + X[:, 1, 1] >= SEGMENT_FAST_MIN_SEMI_MAJOR ** 2).nonzero()[0]
    if len(long_) < 2:
        return est, 0
    major, minor, yaw = (a[long_] for a in est.axes())
    fast = _norm(est.m[long_, 2:], 1) >= SEGMENT_FAST_SPEED
    thin = (minor <= SEGMENT_MAX_SEMI_MINOR) & (
        (major >= SEGMENT_MIN_SEMI_MAJOR) | (fast & (major >= SEGMENT_FAST_MIN_SEMI_MAJOR)))
    seg, major, minor, yaw = long_[thin], major[thin], minor[thin], yaw[thin]
    if len(seg) < 2:
        return est, 0
    u = np.stack([np.cos(yaw), np.sin(yaw)], axis=1)
    half = (0.5 * np.sqrt(3.0)) * major                # half the rectangle's length
    centre = est.m[seg, :2]
    ends = np.concatenate([centre + half[:, None] * u, centre - half[:, None] * u])  # (2s, 2)
    s = len(seg)
    # how near an end of one piece comes to the other piece (the nearest point of its
    # segment: t along it, within its half-length), the nearer of the two ways round
    rel = ends[:, None, :] - centre[None, :, :]                          # (2s, s, 2)
    t = np.clip(np.sum(rel * u[None], axis=2), -half[None], half[None])
    off = rel - t[:, :, None] * u[None]
    d = _norm(off, 2).reshape(2, s, s).min(axis=0)
    d = np.minimum(d, d.T)
    dv = _norm(est.m[seg, None, 2:] - est.m[None, seg, 2:], 2)
    near = (d <= gap) & (dv <= speed)
    np.fill_diagonal(near, False)
    if not np.any(near):
        return est, 0
    parent = list(range(s))
    for i, j in zip(*near.nonzero()):
        union_min(parent, int(i), int(j))
    roots = np.array([find_root(parent, i) for i in range(s)])
    keep = np.ones(k, dtype=bool)
    out = Estimates(est.label.copy(), est.existence.copy(), est.m.copy(), est.P.copy(),
                    est.X.copy(), est.rate.copy(), est.num_detections.copy(),
                    est.visibility.copy())
    grouped = 0
    for r in np.unique(roots):
        members = (roots == r).nonzero()[0]
        if len(members) < 2:
            continue
        rows = seg[members]
        # the longest piece carries the report (ungrouped, it is the one nearest the
        # object), then the most senior: most scans in a row, then the oldest
        head = rows[np.lexsort((est.label[rows], -seniority[rows], -major[members]))[0]]
        ux, uy = u[members[np.argmax(major[members])]]
        frame = np.array([[ux, -uy], [uy, ux]])        # the longest piece's axis, its normal
        pts = np.concatenate([ends[members], ends[s + members]]) @ frame
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        length = hi[0] - lo[0]
        width = hi[1] - lo[1] + np.sqrt(3.0) * minor[members].max()
        w = np.maximum(est.rate[rows], 1e-9)
        out.m[head, :2] = frame @ (0.5 * (lo + hi))
        out.m[head, 2:] = (w[:, None] * est.m[rows, 2:]).sum(axis=0) / w.sum()
        out.X[head] = frame @ np.diag([length ** 2 / 3.0, width ** 2 / 3.0]) @ frame.T
        out.existence[head] = est.existence[rows].max()
        out.visibility[head] = est.visibility[rows].max()
        out.rate[head] = est.rate[rows].sum()
        out.num_detections[head] = est.num_detections[rows].sum()
        keep[rows] = False
        keep[head] = True
        grouped += len(rows) - 1
    return out.take(keep), grouped
