"""
Probability of detection from the scan itself: the scan-shadow model.

Notes
-----
Section 6 of ``docs/ggiw-cphd.md``. For each predicted component the ellipse
``(Hm, E[X])`` subtends an angular interval seen from the sensor (widened by the position
uncertainty across the line of sight) and has a near range ``r_near``. A beam in the
interval is *shadowed* when its return is clearly nearer than ``r_near``; beams with no
return, or a return at or beyond the object, leave it visible. ``p_D = p_D0 * visible``
and ``p_D = 0`` outside the field of view or beyond ``range_max``. The estimate-shadow
mode (Granström & Orguner, IEEE TSP 60(11), 2012) replaces the scan's returns by the near
ranges of the other confident estimates.

"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..ggiw import Mixture
from .scan import ScanPoints

GATHER_WIDTH = 64        # narrowest class of intervals counted in one gather (beams)


@dataclass(frozen=True)
class Visibility:
    """Per-component detection model of one scan (arrays of length n)."""

    p_d: np.ndarray
    visible: np.ndarray
    rate_scale: np.ndarray | None
    offset: np.ndarray | None = None
    outside: np.ndarray | None = None


def _geometry(mix: Mixture, widen_sigmas: float, max_widen: float):
    """
    Bearing, half-width (rad), near and far range of each component's ellipse.

    Returns ``(bearing, half, half_widened, r_near, r_far)``: ``half`` from the expected
    extent alone, ``half_widened`` with ``widen_sigmas`` position stds across the line of
    sight added (at most ``max_widen`` metres).
    """
    c = mix.m[:, :2]
    r = np.hypot(c[:, 0], c[:, 1])
    bearing = np.arctan2(c[:, 1], c[:, 0])
    e = np.column_stack([np.cos(bearing), np.sin(bearing)])      # along the line of sight
    u = np.column_stack([-e[:, 1], e[:, 0]])                     # across it
    X = mix.expected_extent()
    along = np.sqrt(np.maximum(np.einsum('ki,kij,kj->k', e, X, e), 0.0))
    across = np.sqrt(np.maximum(np.einsum('ki,kij,kj->k', u, X, u), 0.0))
    sigma = np.sqrt(np.maximum(np.einsum('ki,kij,kj->k', u, mix.P[:, :2, :2], u), 0.0))
    half = np.stack([across, across + np.minimum(widen_sigmas * sigma, max_widen)])
    with np.errstate(divide='ignore', invalid='ignore'):
        half_angle = np.where(r > half, np.arcsin(np.clip(half / r, 0, 1)), np.pi / 2)
    return bearing, half_angle[0], half_angle[1], np.maximum(r - along, 0.0), r + along


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


def _visible_fraction(bearing, half_angle, r_near, scan: ScanPoints, beam_range, margin):
    """
    Fraction of the beams in each component's interval not blocked by a nearer return.

    ``beam_range`` (B,) holds, per beam in message order, the range that may block (inf
    where nothing does). Beams of the interval outside the field of view count as hidden.
    """
    k = len(bearing)
    if k == 0 or len(scan.angles) == 0:
        return np.zeros(k), bearing.copy()
    order, ang, step = scan.sorted_beams
    rng = beam_range[order]
    lo = np.searchsorted(ang, bearing - half_angle, side='left')
    hi = np.searchsorted(ang, bearing + half_angle, side='right')
    # an interval narrower than the beam spacing still sees its nearest beam
    nearest = np.clip(np.searchsorted(ang, bearing), 0, len(ang) - 1)
    empty = hi <= lo
    lo = np.where(empty, nearest, lo)
    hi = np.where(empty, nearest + 1, hi)
    width = hi - lo
    thr = r_near - margin
    blocked_n = np.zeros(k)
    # intervals whose nearest return is not nearer than the object are all free: their
    # count is the width and their angle sum a prefix-sum difference. Worth it when the
    # intervals hold more beams than the range-minimum table costs (B log2 B).
    if width.sum() > len(ang) * np.log2(max(len(ang), 2)):
        clear = _range_min(rng, lo, hi) >= thr
        cum = np.concatenate([[0.0], np.cumsum(ang)])
        free_sum = np.where(clear, cum[hi] - cum[lo], 0.0)
    else:
        clear = np.zeros(k, dtype=bool)
        free_sum = np.zeros(k)
    # the others: one padded gather per class of widths (up to 64 beams, then doubling),
    # so the work stays within twice their total width and the calls are a handful
    cls = np.maximum(np.ceil(np.log2(np.maximum(width, 1) / GATHER_WIDTH)), 0).astype(int)
    cls[clear] = -1
    for c in np.unique(cls[~clear]).tolist():
        ni = np.flatnonzero(cls == c)
        w_max = int(width[ni].max())
        idx = lo[ni, None] + np.arange(w_max)[None, :]
        inside = idx < hi[ni, None]
        idx = np.minimum(idx, len(ang) - 1)
        blocked = (rng[idx] < thr[ni, None]) & inside
        blocked_n[ni] = blocked.sum(axis=1)
        free_sum[ni] = np.where(inside & ~blocked, ang[idx], 0.0).sum(axis=1)
    frac_visible = 1.0 - blocked_n / width
    n_free = width - blocked_n
    mean_free = np.where(n_free > 0, free_sum / np.maximum(n_free, 1), bearing)
    # part of the interval outside the field of view is not seen at all
    step = max(step, 1e-9)
    span = 2 * half_angle
    covered = np.clip(np.minimum(bearing + half_angle, scan.angle_hi + step / 2)
                      - np.maximum(bearing - half_angle, scan.angle_lo - step / 2), 0.0, None)
    in_fov = np.where(span > 0, np.clip(covered / np.maximum(span, 1e-12), 0.0, 1.0), 1.0)
    centre_in = (bearing >= scan.angle_lo - step / 2) & (bearing <= scan.angle_hi + step / 2)
    return np.where(centre_in, frac_visible * in_fov, 0.0), mean_free


def detection_model(mix: Mixture, scan: ScanPoints | None, cfg,
                    with_offset: bool = True) -> Visibility:
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
    bearing, half, half_widened, r_near, r_far = _geometry(mix, det.widen_sigmas,
                                                          det.max_widen)

    def lookup(half_angle):
        if det.model == 'scan_shadow':
            return _visible_fraction(bearing, half_angle, r_near, scan, scan.ranges,
                                     det.shadow_margin)
        return _estimate_shadow(mix, bearing, half_angle, r_near, r_far, scan, det)

    # p_D from the interval widened by the position uncertainty (capped); the centroid
    # offset from the plain one
    widen = not with_offset or (det.max_widen > 0 and det.widen_sigmas > 0)
    offset = None
    if not with_offset:
        visible, _ = lookup(half_widened)
    else:
        if det.model == 'scan_shadow' and widen:
            # both intervals of every component in one lookup
            both, mean_free = _visible_fraction(
                np.tile(bearing, 2), np.concatenate([half, half_widened]), np.tile(r_near, 2),
                scan, scan.ranges, det.shadow_margin)
            plain, visible, mean_free = both[:n], both[n:], mean_free[:n]
        else:
            plain, mean_free = lookup(half)
            visible = lookup(half_widened)[0] if widen else plain
        # The visible part's centroid sits at the mean unshadowed angle, on the object's
        # near range: an offset across the line of sight from the centre.
        r_c = np.hypot(mix.m[:, 0], mix.m[:, 1])
        across = np.column_stack([-np.sin(bearing), np.cos(bearing)])
        shift = np.where((plain > 0) & (plain < 1), _wrap(mean_free - bearing) * r_c, 0.0)
        offset = across * shift[:, None]
    # wholly out of the field of view or beyond range: the object has left the scene
    step = abs(scan.angle_step)
    outside = ((r_near > scan.range_max) | (bearing + half < scan.angle_lo - step)
               | (bearing - half > scan.angle_hi + step))
    visible = np.where(r_near > scan.range_max, 0.0, visible)
    visible = np.where(visible < det.min_visibility, 0.0, visible)
    rate_scale = np.maximum(visible, 0.05) if det.scale_rate_by_visibility else None
    return Visibility(det.p_d0 * visible, visible, rate_scale, offset, outside)


def _estimate_shadow(mix, bearing, half, r_near, r_far, scan, det, min_weight=0.5):
    """Visible fraction with shadows cast by the other confident components, beam by beam."""
    n = len(mix)
    order, ang_sorted, _ = scan.sorted_beams
    confident = mix.w >= min_weight
    visible = np.ones(n)
    mean_free = bearing.copy()
    # for every component, the blocking range of each beam is the nearest far range of
    # another confident component (of another label) whose interval covers the beam
    for i in range(n):
        others = confident & (mix.label != mix.label[i]) & (r_far < r_near[i])
        if not np.any(others):
            blocking = np.full(len(scan.angles), np.inf)
        else:
            oi = np.flatnonzero(others)
            cover = np.abs(_wrap(ang_sorted[None, :] - bearing[oi, None])) <= half[oi, None]
            near = np.where(cover, r_near[oi, None], np.inf).min(axis=0)
            blocking = np.empty(len(scan.angles))
            blocking[order] = near
        vis_i, mf_i = _visible_fraction(bearing[i:i + 1], half[i:i + 1], r_near[i:i + 1],
                                        scan, blocking, det.shadow_margin)
        visible[i], mean_free[i] = vis_i[0], mf_i[0]
    return visible, mean_free


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
    if det.model != 'scan_shadow' or scan is None or not len(comp):
        return default[comp]
    probe = Mixture(mix.w[comp], mix.alpha[comp], mix.beta[comp], m_updated, P_updated,
                    mix.v[comp], mix.V[comp], mix.label[comp])
    return detection_model(probe, scan, cfg, with_offset=False).p_d
