"""
Probability of detection from the scan itself: the scan-shadow model.

Notes
-----
Section 6 of ``docs/ggiw-cphd.md``. For each predicted component the ellipse
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

from dataclasses import dataclass, fields
import math

import numpy as np

from ..ggiw import inv2, Mixture, quad_form2
from .scan import ScanPoints

GATHER_WIDTH = 64        # narrowest class of intervals counted in one gather (beams)
MIN_RATE_SCALE = 0.05       # least visible fraction a rate is scaled by


@dataclass(frozen=True)
class Visibility:
    """Per-component detection model of one scan (arrays of length n)."""

    p_d: np.ndarray
    visible: np.ndarray
    rate_scale: np.ndarray | None
    offset: np.ndarray | None = None
    outside: np.ndarray | None = None
    shadowed: np.ndarray | None = None     # the plain interval (extent alone) wholly shadowed
    at_sensor: np.ndarray | None = None    # the sensor within the outline: not an object
    sparse: np.ndarray | None = None       # in view, far fewer returns than beams spanned

    def take(self, rows) -> 'Visibility':
        """The model of the components ``rows`` (an index or mask), every field alike."""
        values = (getattr(self, f.name) for f in fields(self))
        return Visibility(*(None if a is None else a[rows] for a in values))


def _geometry(m: np.ndarray, X: np.ndarray, P: np.ndarray, widen_sigmas: float,
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


def _range_min(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
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


def _visible_fraction(bearing, half_angle, r_near, scan: ScanPoints, beam_range, margin,
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
    full = scan.full_turn
    if full:                 # the seam has beams on both sides: no edge cuts an interval
        order, ang = scan.wrapped_beams
        rng = beam_range[order]
    else:
        rng = scan.sorted_ranges if beam_range is scan.ranges else beam_range[order]
    lo = ang.searchsorted(bearing - half_angle, side='left')
    hi = ang.searchsorted(bearing + half_angle, side='right')
    # an interval narrower than the beam spacing still sees its nearest beam: the one
    # just below the bearing or the one above it (where an empty interval's lo points),
    # whichever is nearer
    empty = hi <= lo
    if np.any(empty):
        e = empty.nonzero()[0]
        up = np.minimum(lo[e], len(ang) - 1)
        down = np.maximum(up - 1, 0)
        nearest = np.where(bearing[e] - ang[down] < ang[up] - bearing[e], down, up)
        lo[e], hi[e] = nearest, nearest + 1
    width = hi - lo
    thr = r_near - margin
    blocked_n = np.zeros(k)
    # intervals whose nearest return is not nearer than the object are all free: their
    # count is the width and their free beams are all their beams. Worth it when the
    # intervals hold more beams than the range-minimum table costs (B log2 B).
    if np.sum(width) > len(ang) * math.log2(max(len(ang), 2)):
        classes = _width_classes(width, _range_min(rng, lo, hi) >= thr)
    elif width.max() <= GATHER_WIDTH:
        classes = [None]                   # the usual case: every interval in one gather
    else:
        classes = _width_classes(width, np.zeros(k, dtype=bool))
    if with_shift:
        free_turn = np.zeros(k)            # mean free angle less the mean of all, per row
    # the others: one padded gather per class of widths (up to 64 beams, then doubling),
    # so the work stays within twice their total width and the calls are a handful
    for ni in classes:
        if ni is None:
            lo_i, hi_i, thr_i, width_i = lo, hi, thr, width
        else:
            lo_i, hi_i, thr_i, width_i = lo[ni], hi[ni], thr[ni], width[ni]
        idx = lo_i[:, None] + np.arange(int(width_i.max()))[None, :]
        inside = idx < hi_i[:, None]
        idx = np.minimum(idx, len(ang) - 1)
        blocked = (rng[idx] < thr_i[:, None]) & inside
        n_blocked = blocked.sum(axis=1)
        blocked_n[slice(None) if ni is None else ni] = n_blocked
        if with_shift:
            # only partly blocked intervals turn (the others stay exactly 0), and only
            # those whose shift is asked for
            n_free = width_i - n_blocked
            part = (n_blocked > 0) & (n_free > 0)
            if shift_rows is not None:
                if ni is None:
                    part[shift_rows:] = False
                else:
                    part &= ni < shift_rows
            rows = part.nonzero()[0]
            if len(rows):
                a = np.where(inside[rows], ang[idx[rows]], 0.0)
                free_sum = np.where(blocked[rows], 0.0, a).sum(axis=1)
                free_turn[rows if ni is None else ni[rows]] = (
                    free_sum / n_free[rows] - a.sum(axis=1) / width_i[rows])
    frac_visible = 1.0 - blocked_n / width
    # part of the interval outside the field of view is not seen at all: the lengths cut
    # off each end are exactly 0 where the field of view holds it
    cut_lo = cut_hi = 0.0
    if full:
        visible = frac_visible
    else:
        step = max(step, 1e-9)
        start, end = bearing - half_angle, bearing + half_angle
        fov_lo, fov_hi = scan.angle_lo - step / 2, scan.angle_hi + step / 2
        if (np.min(start, initial=np.inf) >= fov_lo
                and np.max(end, initial=-np.inf) <= fov_hi):
            # every interval within the field of view (most scans): nothing cut off, the
            # lengths below would be exactly 0 and the factor exactly 1
            visible = frac_visible
        else:
            cut_lo, cut_hi, visible = _fov_cut(start, end, fov_lo, fov_hi, half_angle,
                                               frac_visible)
    if not with_shift:
        return visible, None
    shift = np.where(visible > 0.0, free_turn + 0.5 * (cut_lo - cut_hi), 0.0)
    if shift_rows is not None:
        shift[shift_rows:] = 0.0
    return visible, shift


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


def detection_model(mix: Mixture, scan: ScanPoints | None, cfg) -> Visibility:
    """
    p_D of every predicted component for one scan, by ``cfg.detection.model``.

    Parameters
    ----------
    mix : Mixture
        Predicted mixture.
    scan : ScanPoints or None
        The scan (None for constant p_D without a scan).
    cfg : TrackerConfig

    """
    det = cfg.detection
    n = len(mix)
    if det.model == 'constant' or scan is None or n == 0:
        ones = np.ones(n)
        return Visibility(np.full(n, det.p_d0), ones, None)
    extent = mix.expected_extent()
    bearing, half, half_widened, r_near, r_far, r_c, u = _geometry(
        mix.m, extent, mix.P, det.widen_sigmas, det.max_widen)
    bearing = scan.in_scan_frame(bearing)

    def lookup(half_angle):
        if det.model == 'scan_shadow':
            return _visible_fraction(bearing, half_angle, r_near, scan, scan.ranges,
                                     det.shadow_margin)
        return _estimate_shadow(bearing, half_angle, r_near, mix.label,
                                _occluders(mix, bearing, half, r_near, r_far), scan, det)

    # p_D from the interval widened by the position uncertainty (capped); the centroid
    # offset from the plain one
    widen = det.max_widen > 0 and det.widen_sigmas > 0
    if det.model == 'scan_shadow' and widen:
        # both intervals of every component in one lookup
        both, turn = _visible_fraction(
            np.concatenate([bearing, bearing]), np.concatenate([half, half_widened]),
            np.concatenate([r_near, r_near]), scan, scan.ranges, det.shadow_margin,
            shift_rows=n)                             # the offset is the plain interval's
        plain, visible, turn = both[:n], both[n:], turn[:n]
    else:
        plain, turn = lookup(half)
        visible = lookup(half_widened)[0] if widen else plain
    offset = _centroid_offset(extent, u, turn * r_c)
    # wholly out of the field of view or beyond range: the object has left the scene
    step = abs(scan.angle_step)
    outside = r_near > scan.range_max
    if not scan.full_turn:
        outside |= ((bearing + half < scan.angle_lo - step)
                    | (bearing - half > scan.angle_hi + step))
    # the sensor inside the outline (the ellipse of E[X]: squared Mahalanobis distance
    # below 1): no object can be there. Its interval is taken as half a turn about its
    # bearing, which may point out of the field of view (p_D down to 0): clutter around
    # the sensor kept such tracks alive
    at_sensor = _holds_sensor(mix.m, extent)
    sparse = _sparse(mix, half, plain, step, det.min_fill)
    visible = _seen(visible, r_near, scan, det)
    rate_scale = np.maximum(visible, MIN_RATE_SCALE) if det.scale_rate_by_visibility else None
    return Visibility(det.p_d0 * visible, visible, rate_scale, offset, outside, plain == 0.0,
                      at_sensor, sparse)


def _holds_sensor(m: np.ndarray, extent: np.ndarray) -> np.ndarray:
    """Whether the sensor (the origin) lies within each outline, the ellipse of the
    expected extent ``extent`` about the centre ``m[:, :2]``."""
    return quad_form2(m[:, :2], inv2(extent)) < 1.0


# visible fraction of its own extent from which the scan shows an object's returns (all
# but a tenth of the beams it spans free of nearer returns): a lone clutter return 0.3 m
# from the scanner shadows one beam of the 50-180 a track near it spans
IN_VIEW = 0.9


def _sparse(mix: Mixture, half: np.ndarray, plain: np.ndarray, step: float,
            min_fill: float) -> np.ndarray:
    """
    Components in view that expect fewer returns than ``min_fill`` of the beams their
    extent spans: no object a laser sees.

    Notes
    -----
    A laser returns on nearly every beam that a solid object in full view spans (a
    walker's two legs at leg height on about half of the beams across both), so an
    object's expected returns per scan, the Gamma mean of its rate, are about the beams
    it spans, ``2 half / step`` (``half`` the half-angle of its expected extent across
    the line of sight, ``step`` the beam spacing). A component expecting a tenth of that
    is made of returns scattered over an area no one surface fills: a few clutter returns
    near the scanner, where the beams are dense and one clutter return lies centimetres
    from the next, born as an object of the birth prior's size (0.25 m at 0.35 m from
    the scanner spans some 180 beams of 0.5 deg) that expects 2 returns. In ``clutter``
    such tracks lived for scans on the clutter around the scanner and took the weight of
    a hidden walker's label with them. The test is made only where the scan shows the
    object (``plain``, the extent's own visible fraction, at least ``IN_VIEW``): of an
    object mostly or wholly hidden the scan says nothing, and its rate is its full-view
    rate.
    """
    if min_fill <= 0.0 or not step > 0.0:            # no beam spacing: no beams to count
        return np.zeros(len(mix), dtype=bool)
    return (plain >= IN_VIEW) & _expects_too_few(mix.expected_rate(), half, step, min_fill)


def _expects_too_few(rate: np.ndarray, half: np.ndarray, step: float,
                     min_fill: float) -> np.ndarray:
    """Whether each expected rate is below ``min_fill`` of the beams, ``2 half / step``, an
    extent of half-angle ``half`` spans (the test of :func:`_sparse`, for tracks and births
    alike)."""
    return rate < min_fill * (2.0 * half / step)


def sparse_births(births, scan: ScanPoints, cfg) -> np.ndarray:
    """
    The birth hypotheses ``births`` (the posteriors of the cells' births, a
    :class:`ggiw.PairUpdate`) that would be ``sparse`` (:func:`_sparse`) in this very scan,
    in view and expecting fewer returns than ``detection.min_fill`` of the beams they
    span, or whose outline holds the sensor (``at_sensor``). Only with the scan-shadow
    model.

    Notes
    -----
    Checking the predicted components drops such a track a scan after its birth, but in
    the CPHD its birth has by then taken its weight from the labels the scan does not
    see: in ``clutter`` a track born on the clutter 0.85 m from the scanner took a hidden
    person's label from 1.32 to 0.43 in its birth scan, and the label was not reported
    again until the person came back into view. So a birth is also checked in its own
    scan, before the update weighs it. Most scans have no birth that could fail: a bound
    (the extent's largest semi-axis is at most ``sqrt(trace E[X])``) rules them out before
    the exact half-angles and the visibility lookup are computed.
    """
    det = cfg.detection
    n = len(births.alpha)
    none = np.zeros(n, dtype=bool)
    step = abs(scan.angle_step)
    if det.model != 'scan_shadow' or det.min_fill <= 0.0 or n == 0 or not step > 0.0:
        return none
    as_mix = births.mixture(np.ones(n), np.zeros(n, dtype=np.int64))  # for E[X], E[gamma]
    extent = as_mix.expected_extent()
    r = np.hypot(births.m[:, 0], births.m[:, 1])
    reach = np.sqrt(extent[:, 0, 0] + extent[:, 1, 1])
    widest = np.arcsin(np.minimum(reach / np.maximum(r, 1e-9), 1.0))   # half-angle bound
    rate = as_mix.expected_rate()
    maybe = (_expects_too_few(rate, widest, step, det.min_fill) | (r < reach)).nonzero()[0]
    if not len(maybe):
        return none
    bearing, half, _, r_near, _, _, _ = _geometry(births.m[maybe], extent[maybe],
                                                  births.P[maybe], 0.0, 0.0)
    at_sensor = _holds_sensor(births.m[maybe], extent[maybe])
    low = _expects_too_few(rate[maybe], half, step, det.min_fill)
    if np.any(low):
        rows = low.nonzero()[0]
        plain, _ = _visible_fraction(scan.in_scan_frame(bearing[rows]), half[rows],
                                     r_near[rows], scan, scan.ranges, det.shadow_margin,
                                     shift_rows=0)
        low[rows] = plain >= IN_VIEW
    none[maybe] = low | at_sensor
    return none


def _centroid_offset(X: np.ndarray, u: np.ndarray, shift: np.ndarray) -> np.ndarray:
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
    if not np.any(shift != 0.0):
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
        if not np.any(others):
            blocking = np.full(len(scan.angles), np.inf)
        else:
            oi = others.nonzero()[0]
            cover = (np.abs(_wrap(ang_sorted[None, :] - o_bearing[oi, None]))
                     <= o_half[oi, None])
            near = np.where(cover, o_near[oi, None], np.inf).min(axis=0)
            blocking = np.empty(len(scan.angles))
            blocking[order] = near
        vis_i, turn_i = _visible_fraction(bearing[i:i + 1], half[i:i + 1], r_near[i:i + 1],
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


def pair_detection_probability(mix: Mixture, comp: np.ndarray, m_updated: np.ndarray,
                               P_updated: np.ndarray, scan: ScanPoints | None, cfg,
                               default: np.ndarray) -> np.ndarray:
    """
    p_D of (component, cell) pairs, evaluated where the cell puts the object.

    Notes
    -----
    The detection term of the update is ``integral p_D(x) l(W|x) N(x) dx``; with ``p_D``
    smooth on the scale of the posterior it is ``p_D(x_W) integral l N``, ``x_W`` the
    posterior mean given ``W``. Evaluating it at the *predicted* mean instead would forbid
    a track that coasted behind an occluder (p_D = 0 there) from claiming its object's
    first points when they reappear a little ahead of the prediction.
    """
    det = cfg.detection
    if det.model == 'constant' or scan is None or not len(comp):
        return default[comp]
    # the widened interval of each pair, as detection_model gives it for a component
    bearing, _, half_widened, r_near, *_ = _geometry(
        m_updated, mix.expected_extent(comp), P_updated, det.widen_sigmas, det.max_widen)
    bearing = scan.in_scan_frame(bearing)
    if det.model == 'scan_shadow':
        visible, _ = _visible_fraction(bearing, half_widened, r_near, scan, scan.ranges,
                                       det.shadow_margin, shift_rows=0)
    else:
        # the other labels' predicted components cast the shadows
        o_bearing, o_half, _, o_near, o_far, *_ = _geometry(
            mix.m, mix.expected_extent(), mix.P, det.widen_sigmas, det.max_widen)
        visible, _ = _estimate_shadow(
            bearing, half_widened, r_near, mix.label[comp],
            _occluders(mix, o_bearing, o_half, o_near, o_far), scan, det)
    return det.p_d0 * _seen(visible, r_near, scan, det)
