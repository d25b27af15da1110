"""
The detection model of one scan: p_D, visible fraction, centroid offset and rate scale
of each predicted component (:func:`detection_model`), of each updated pair
(:func:`pair_detection_probability`) and of each birth hypothesis (:func:`sparse_births`).

The geometry of shadows is in :mod:`sensing.shadow`; ``doc/model.md``, section 6.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ..filter.algebra2 import inv2, quad_form2
from ..filter.mixture import Mixture
from .scan import ScanPoints
from .shadow import (
    _estimate_shadow, _occluders, _seen, ellipse_geometry, visible_centroid_offset,
    visible_fraction,
)

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
    in_open: np.ndarray | None = None      # no background return in front

    def take(self, rows) -> 'Visibility':
        """The model of the components ``rows`` (an index or mask), every field alike."""
        values = (getattr(self, f.name) for f in fields(self))
        return Visibility(*(None if a is None else a[rows] for a in values))


def detection_model(mix: Mixture, scan: ScanPoints | None, cfg,
                    foreground: np.ndarray | None = None) -> Visibility:
    """
    p_D of every predicted component for one scan, by ``cfg.detection.model``.

    Parameters
    ----------
    mix : Mixture
        Predicted mixture.
    scan : ScanPoints or None
        The scan (None for constant p_D without a scan).
    cfg : TrackerConfig
    foreground : (B,) bool array, optional
        The beams whose return is no background (reaches the filter); with it the model
        says which components are ``in_open`` (:func:`_in_the_open`).

    """
    det = cfg.detection
    n = len(mix)
    if det.model == 'constant' or scan is None or n == 0:
        ones = np.ones(n)
        return Visibility(np.full(n, det.p_d0), ones, None)
    extent = mix.expected_extent()
    bearing, half, half_widened, r_near, r_far, r_c, u = ellipse_geometry(
        mix.m, extent, mix.P, det.widen_sigmas, det.max_widen)
    bearing = scan.in_scan_frame(bearing)

    def lookup(half_angle):
        if det.model == 'scan_shadow':
            return visible_fraction(bearing, half_angle, r_near, scan, scan.ranges,
                                     det.shadow_margin)
        return _estimate_shadow(bearing, half_angle, r_near, mix.label,
                                _occluders(mix, bearing, half, r_near, r_far), scan, det)

    # p_D from the interval widened by the position uncertainty (capped); the centroid
    # offset from the plain one
    widen = det.max_widen > 0 and det.widen_sigmas > 0
    if det.model == 'scan_shadow' and widen:
        # both intervals of every component in one lookup
        both, turn = visible_fraction(
            np.concatenate([bearing, bearing]), np.concatenate([half, half_widened]),
            np.concatenate([r_near, r_near]), scan, scan.ranges, det.shadow_margin,
            shift_rows=n)                             # the offset is the plain interval's
        plain, visible, turn = both[:n], both[n:], turn[:n]
    else:
        plain, turn = lookup(half)
        visible = lookup(half_widened)[0] if widen else plain
    offset = visible_centroid_offset(extent, u, turn * r_c)
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
    # without the background a wall and a person are alike: no answer
    in_open = (None if foreground is None
               else _in_the_open(bearing, half, r_near, scan, foreground, det))
    return Visibility(det.p_d0 * visible, visible, rate_scale, offset, outside, plain == 0.0,
                      at_sensor, sparse, in_open)


def _in_the_open(bearing, half, r_near, scan: ScanPoints, foreground: np.ndarray,
                 det) -> np.ndarray:
    """
    Which components have no background return nearer than them in their interval
    (``foreground``: the beams whose return is no background): hidden by people, or by
    nothing.

    A walker hidden in a crowd stays in the shadow of the people in front, and comes out
    where it was heading; behind a wall or a cabinet it may have gone anywhere, and a
    static spot that took one stray return can walk off there (doc/model.md 4).
    """
    static = np.where(foreground, np.inf, scan.ranges)
    seen = visible_fraction(bearing, half, r_near, scan, static, det.shadow_margin,
                            shift_rows=0)[0]
    return seen == 1.0


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
    :class:`filter.ggiw.PairUpdate`) that would be ``sparse`` (:func:`_sparse`) in this very scan,
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
    bearing, half, _, r_near, _, _, _ = ellipse_geometry(births.m[maybe], extent[maybe],
                                                  births.P[maybe], 0.0, 0.0)
    at_sensor = _holds_sensor(births.m[maybe], extent[maybe])
    low = _expects_too_few(rate[maybe], half, step, det.min_fill)
    if low.any():
        rows = low.nonzero()[0]
        plain, _ = visible_fraction(scan.in_scan_frame(bearing[rows]), half[rows],
                                     r_near[rows], scan, scan.ranges, det.shadow_margin,
                                     shift_rows=0)
        low[rows] = plain >= IN_VIEW
    none[maybe] = low | at_sensor
    return none


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
    bearing, _, half_widened, r_near, *_ = ellipse_geometry(
        m_updated, mix.expected_extent(comp), P_updated, det.widen_sigmas, det.max_widen)
    bearing = scan.in_scan_frame(bearing)
    if det.model == 'scan_shadow':
        visible, _ = visible_fraction(bearing, half_widened, r_near, scan, scan.ranges,
                                       det.shadow_margin, shift_rows=0)
    else:
        # the other labels' predicted components cast the shadows
        o_bearing, o_half, _, o_near, o_far, *_ = ellipse_geometry(
            mix.m, mix.expected_extent(), mix.P, det.widen_sigmas, det.max_widen)
        visible, _ = _estimate_shadow(
            bearing, half_widened, r_near, mix.label[comp],
            _occluders(mix, o_bearing, o_half, o_near, o_far), scan, det)
    return det.p_d0 * _seen(visible, r_near, scan, det)
