"""
Probability of detection from the scan itself: the scan-shadow model.

Notes
-----
Section 6 of ``doc/model.md``. For each predicted component the ellipse
``(Hm, E[X])`` subtends an angular interval seen from the sensor (widened by the position
uncertainty across the line of sight) and has a near range ``r_near``. A beam in the
interval is *shadowed* when its return is clearly nearer than ``r_near``; beams with no
return, or a return at or beyond the object, leave it visible. ``p_D = p_D0 * visible``
and ``p_D = 0`` outside the field of view or beyond ``range_max``; a component whose
outline holds the sensor is marked ``at_sensor`` (no object can be there). The
estimate-shadow mode (Granström & Orguner, IEEE TSP 60(11), 2012) replaces the scan's
returns by the near ranges of the other confident estimates.

"""

from __future__ import annotations

import math

import numpy as np

from ..filter.mixture import Mixture
from .scan import ScanPoints

GATHER_WIDTH = 64        # narrowest class of intervals counted in one gather (beams)


def ellipse_geometry(m: np.ndarray, X: np.ndarray, P: np.ndarray, widen_sigmas: float,
              max_widen: float):
    """
    Bearing, half-width (rad), near and far range of each component's ellipse.

    ``m`` (k, 4) are the kinematic means, ``X`` (k, 2, 2) the expected extents and ``P``
    (k, 4, 4) the kinematic covariances. Returns ``(bearing, half, half_widened, r_near,
    r_far, r, u)``: ``half`` from the expected extent alone, ``half_widened`` with
    ``widen_sigmas`` position stds across the line of sight added (at most ``max_widen``
    metres); ``r`` the centre's range and ``u`` (k, 2) the unit vector across the line of
    sight.
    """
    k = len(m)
    r = np.hypot(m[:, 0], m[:, 1])
    bearing = np.arctan2(m[:, 1], m[:, 0])
    e = np.empty((k, 2))                                         # along the line of sight
    np.cos(bearing, out=e[:, 0])
    np.sin(bearing, out=e[:, 1])
    u = e[:, ::-1] * _ACROSS                                     # across it
    along = np.sqrt(np.maximum(np.einsum('ki,kij,kj->k', e, X, e), 0.0))
    across = np.sqrt(np.maximum(np.einsum('ki,kij,kj->k', u, X, u), 0.0))
    sigma = np.sqrt(np.maximum(np.einsum('ki,kij,kj->k', u, P[:, :2, :2], u), 0.0))
    half = np.empty((2, k))
    half[0] = across
    np.add(across, np.minimum(widen_sigmas * sigma, max_widen), out=half[1])
    # asin(half / r) where the sensor lies outside the half-width, else pi / 2 (asin 1;
    # the division is skipped there: r may be 0)
    ratio = np.divide(half, r, out=np.ones((2, k)), where=r > half)
    half_angle = np.arcsin(np.minimum(np.maximum(ratio, 0.0), 1.0))
    return bearing, half_angle[0], half_angle[1], np.maximum(r - along, 0.0), r + along, r, u


_ACROSS = np.array([-1.0, 1.0])      # (cos, sin) reversed times this is (-sin, cos)


def range_min_over(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """
    ``min(values[lo:hi])`` of many non-empty ranges at once, by a sparse table.

    Level ``l`` holds the minima of the ``2**l`` values from each position; a range is
    covered by two (overlapping) blocks of the largest level that fits it.
    """
    n = len(values)
    levels = [values]
    size = 1
    while 2 * size <= n:
        prev = levels[-1]
        levels.append(np.minimum(prev[:len(prev) - size], prev[size:]))
        size *= 2
    table = np.full((len(levels), n), np.inf)
    for lev, row in enumerate(levels):
        table[lev, :len(row)] = row
    width = np.maximum(hi - lo, 1)
    lev = np.floor(np.log2(width)).astype(np.int64)
    span = np.left_shift(1, lev)
    return np.minimum(table[lev, lo], table[lev, np.maximum(hi - span, lo)])


def visible_fraction(bearing, half_angle, r_near, scan: ScanPoints, beam_range, margin,
                      shift_rows: int | None = None):
    """
    Fraction of the beams in each component's interval not blocked by a nearer return,
    and the angle (rad) from ``bearing`` to the middle of the part that is seen (0 where
    nothing is) for the first ``shift_rows`` intervals (all of them when None; the others
    read 0, and with ``shift_rows=0`` the shift is ``None``: its sums are saved).

    ``beam_range`` (B,) holds, per beam in message order, the range that may block (inf
    where nothing does). Beams of the interval outside the field of view count as hidden,
    whether or not the centre is in it.

    Both are exact where nothing hides the interval: the fraction is 1 and the shift 0, not
    a rounding away from them. The shift is the mean angle of the free beams less that of
    all the interval's beams (the beam grid's own offset from the bearing cancels), plus
    the shift of the interval's middle where the field of view cuts it.
    """
    k = len(bearing)
    with_shift = shift_rows is None or shift_rows > 0
    if k == 0 or len(scan.angles) == 0:
        return np.zeros(k), (np.zeros(k) if with_shift else None)
    order, ang, step = scan.sorted_beams
    if scan.full_turn:       # the seam has beams on both sides: no edge cuts an interval
        order, ang = scan.wrapped_beams
        rng = beam_range[order]
    else:
        rng = scan.sorted_ranges if beam_range is scan.ranges else beam_range[order]
    lo, hi = _beam_intervals(ang, bearing, half_angle)
    width = hi - lo
    blocked_n, free_turn = _count_blocked(ang, rng, lo, hi, r_near - margin, with_shift,
                                          shift_rows)
    frac_visible = 1.0 - blocked_n / width
    cut_lo, cut_hi, visible = _in_view(scan, step, bearing, half_angle, frac_visible)
    if not with_shift:
        return visible, None
    shift = np.where(visible > 0.0, free_turn + 0.5 * (cut_lo - cut_hi), 0.0)
    if shift_rows is not None:
        shift[shift_rows:] = 0.0
    return visible, shift


def _beam_intervals(ang: np.ndarray, bearing, half_angle):
    """
    ``(lo, hi)``: the beams (sorted angles ``ang``) of each interval. An interval narrower
    than the beam spacing still sees its nearest beam: the one just below the bearing or
    the one above it (where an empty interval's ``lo`` points), whichever is nearer.
    """
    lo = ang.searchsorted(bearing - half_angle, side='left')
    hi = ang.searchsorted(bearing + half_angle, side='right')
    empty = hi <= lo
    if empty.any():
        e = empty.nonzero()[0]
        up = np.minimum(lo[e], len(ang) - 1)
        down = np.maximum(up - 1, 0)
        nearest = np.where(bearing[e] - ang[down] < ang[up] - bearing[e], down, up)
        lo[e], hi[e] = nearest, nearest + 1
    return lo, hi


def _count_blocked(ang, rng, lo, hi, thr, with_shift: bool, shift_rows):
    """
    Beams of each interval ``[lo, hi)`` whose range is below ``thr``, and (``with_shift``)
    the mean angle of the free beams less that of all the interval's beams.

    One padded gather per class of widths (up to ``GATHER_WIDTH`` beams, then doubling),
    so the work stays within twice the intervals' total width and the calls are a
    handful. Intervals whose nearest return is not nearer than the object are all free:
    their count is the width, which pays when the intervals hold more beams than the
    range-minimum table costs (B log2 B).
    """
    k, width = len(lo), hi - lo
    blocked_n = np.zeros(k)
    free_turn = np.zeros(k) if with_shift else None
    if np.sum(width) > len(ang) * math.log2(max(len(ang), 2)):
        classes = _width_classes(width, range_min_over(rng, lo, hi) >= thr)
    elif width.max() <= GATHER_WIDTH:
        classes = [np.arange(k)]           # the usual case: every interval in one gather
    else:
        classes = _width_classes(width, np.zeros(k, dtype=bool))
    for ni in classes:
        lo_i, hi_i, thr_i, width_i = lo[ni], hi[ni], thr[ni], width[ni]
        idx = lo_i[:, None] + np.arange(int(width_i.max()))[None, :]
        inside = idx < hi_i[:, None]
        idx = np.minimum(idx, len(ang) - 1)
        blocked = (rng[idx] < thr_i[:, None]) & inside
        n_blocked = blocked.sum(axis=1)
        blocked_n[ni] = n_blocked
        if not with_shift:
            continue
        # only partly blocked intervals turn (the others stay exactly 0), and only those
        # whose shift is asked for
        n_free = width_i - n_blocked
        part = (n_blocked > 0) & (n_free > 0)
        if shift_rows is not None:
            part &= ni < shift_rows
        rows = part.nonzero()[0]
        if len(rows):
            a = np.where(inside[rows], ang[idx[rows]], 0.0)
            free_sum = np.where(blocked[rows], 0.0, a).sum(axis=1)
            free_turn[ni[rows]] = free_sum / n_free[rows] - a.sum(axis=1) / width_i[rows]
    return blocked_n, free_turn


def _in_view(scan: ScanPoints, step: float, bearing, half_angle, frac_visible):
    """
    ``(cut_lo, cut_hi, visible)``: the part of each interval outside the field of view is
    not seen at all; the lengths cut off each end are exactly 0 where the field of view
    holds it.
    """
    if scan.full_turn:
        return 0.0, 0.0, frac_visible
    step = max(step, 1e-9)
    start, end = bearing - half_angle, bearing + half_angle
    fov_lo, fov_hi = scan.angle_lo - step / 2, scan.angle_hi + step / 2
    if np.min(start, initial=np.inf) >= fov_lo and np.max(end, initial=-np.inf) <= fov_hi:
        # every interval within the field of view (most scans): nothing cut off
        return 0.0, 0.0, frac_visible
    return _fov_cut(start, end, fov_lo, fov_hi, half_angle, frac_visible)


def _fov_cut(start, end, fov_lo, fov_hi, half_angle, frac_visible):
    """
    The angles cut off each end of the intervals ``[start, end]`` by the field of view
    ``[fov_lo, fov_hi]`` (exactly 0 where it holds them) and the visible fraction
    ``frac_visible`` of the beams times the part in view.
    """
    cut_lo = np.maximum(np.minimum(fov_lo, end) - start, 0.0)
    cut_hi = np.maximum(end - np.maximum(fov_hi, start), 0.0)
    span = 2 * half_angle
    in_fov = np.where(span > 0, np.minimum(np.maximum(
        1.0 - (cut_lo + cut_hi) / np.maximum(span, 1e-12), 0.0), 1.0), 1.0)
    # wherever the centre is: an object leaving across the edge is seen in part until
    # it has gone (with p_D 0 once its centre crossed, no scan refuted the moving
    # track, and a restart at rest on the part still in view took its label); an
    # interval wholly outside reads exactly 0, not the rounding residue of 1 - cut/span
    visible = np.where((end < fov_lo) | (start > fov_hi), 0.0, frac_visible * in_fov)
    return cut_lo, cut_hi, visible


def _width_classes(width: np.ndarray, clear: np.ndarray) -> list:
    """
    The intervals not already known to be clear, grouped for padded gathers: up to
    ``GATHER_WIDTH`` beams, then classes of doubling width (each gather pads its rows to
    its widest, so the work stays within twice the intervals' total width).
    """
    todo = (~clear).nonzero()[0]
    if not len(todo):
        return []
    if width[todo].max() <= GATHER_WIDTH:
        return [todo]                                 # the usual case: one class
    cls = np.maximum(np.ceil(np.log2(np.maximum(width, 1) / GATHER_WIDTH)), 0).astype(int)
    cls[clear] = -1
    return [(cls == c).nonzero()[0] for c in np.unique(cls[todo]).tolist()]


def visible_centroid_offset(X: np.ndarray, u: np.ndarray, shift: np.ndarray) -> np.ndarray:
    """
    Offset (k, 2) of the visible part's centroid from the centre of each component.

    ``X`` (k, 2, 2) are the expected extents, ``u`` (k, 2) the unit vectors across the
    line of sight and ``shift`` (k,) how far across it the middle of the unshadowed beams
    lies from the centre's bearing (m, at the centre's range): exactly 0 for an object in
    full view, and then so is the offset.

    Notes
    -----
    A beam crosses the object along the line of sight, and the middles of those chords
    lie on the diameter conjugate to it, through the centre along ``X u`` (for ``x`` on
    it, ``x^T X^-1 e = 0`` with ``e`` along the line of sight). The centroid of the
    visible part moves along that diameter, by ``shift`` across the line of sight:
    ``offset = X u shift / (u^T X u)``. For a round object it is ``u shift``, across the
    line of sight; for a long one seen obliquely (a car's side) it is along the object.
    Taken across the line of sight there, it put the expected centroid off the side's
    line, where the side's thin extent holds it to centimetres, and the track's velocity
    turned off the car's heading until the gate let go of its returns.
    """
    if not (shift != 0.0).any():
        # nothing part hidden (most scans): the offsets are all 0 without the products
        return np.zeros((len(shift), 2))
    Xu = np.einsum('kij,kj->ki', X, u)
    uXu = np.einsum('ki,ki->k', u, Xu)
    # an object thin across the line of sight (seen end on) has no width to shift along
    scale = np.divide(shift, uXu, out=np.zeros(len(shift)), where=uXu > 1e-12)
    return Xu * scale[:, None]


def _seen(visible, r_near, scan: ScanPoints, det) -> np.ndarray:
    """The visible fraction, 0 beyond the scan's range or under ``min_visibility``."""
    # one selection: a fraction the range test zeroes is under the minimum, or is the 0
    # the minimum keeps
    return np.where((r_near > scan.range_max) | (visible < det.min_visibility), 0.0, visible)


def _estimate_shadow(bearing, half, r_near, label, occluders, scan, det):
    """
    Visible fraction of each interval (``bearing``, ``half``, ``r_near``, of an object
    labelled ``label``) with shadows cast by the other labels' confident components,
    ``occluders`` (:func:`_occluders`), beam by beam.

    An occluder casts the shadow of its plain extent. Widened by its own position
    uncertainty it would hide more than it does: a standing person's shadow 2 degrees
    wider on each side than its silhouette halved the p_D of a walker passing behind it
    while most of the walker was in view, and the walker's track, updated as mostly
    hidden, lagged and lost it (``test_shadow``).
    """
    o_bearing, o_half, o_near, o_far, o_label = occluders
    order, ang_sorted, _ = scan.sorted_beams
    n = len(bearing)
    visible = np.ones(n)
    turn = np.zeros(n)
    # the blocking range of each beam is the nearest near range of an occluder in front
    # whose interval covers the beam
    for i in range(n):
        others = (o_label != label[i]) & (o_far < r_near[i])
        if not others.any():
            blocking = np.full(len(scan.angles), np.inf)
        else:
            oi = others.nonzero()[0]
            cover = (np.abs(_wrap(ang_sorted[None, :] - o_bearing[oi, None]))
                     <= o_half[oi, None])
            near = np.where(cover, o_near[oi, None], np.inf).min(axis=0)
            blocking = np.empty(len(scan.angles))
            blocking[order] = near
        vis_i, turn_i = visible_fraction(bearing[i:i + 1], half[i:i + 1], r_near[i:i + 1],
                                          scan, blocking, det.shadow_margin)
        visible[i], turn[i] = vis_i[0], turn_i[0]
    return visible, turn


def _occluders(mix: Mixture, bearing, half, r_near, r_far, min_weight: float = 0.5):
    """The confident components (weight at least ``min_weight``) as occluders for
    :func:`_estimate_shadow`: their bearing, plain half-width, near and far range, label."""
    c = mix.w >= min_weight
    return bearing[c], half[c], r_near[c], r_far[c], mix.label[c]


def _wrap(a):
    return (a + np.pi) % (2 * np.pi) - np.pi
