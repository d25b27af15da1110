"""
LaserScan to Cartesian detections, with every invalid beam masked and counted.

The scan is read through a small protocol: ``angle_min``, ``angle_increment``,
``range_min``, ``range_max``, ``ranges`` and ``header.stamp`` (``sec``, ``nanosec``);
``angle_max`` and ``header.frame_id`` are used when present. rclpy messages, rosbags
messages and :class:`ScanData` all fit it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
import math

import numpy as np

from ..errors import ScanError

INVALID_KINDS = ('nan', 'pos_inf', 'neg_inf', 'below_min', 'above_max')
# beam clutter density (ScanPoints.beam_clutter_log_density) is held at its value here
# nearer the scanner, where 1 / r would grow without bound
BEAM_CLUTTER_MIN_RANGE = 0.1        # m


@dataclass
class Stamp:
    """``builtin_interfaces/Time`` lookalike."""

    sec: int = 0
    nanosec: int = 0


@dataclass
class Header:
    """``std_msgs/Header`` lookalike."""

    stamp: Stamp = field(default_factory=Stamp)
    frame_id: str = 'laser'


@dataclass
class ScanData:
    """A plain ``sensor_msgs/LaserScan`` lookalike (simulator output, tests)."""

    header: Header
    angle_min: float
    angle_max: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray
    time_increment: float = 0.0
    scan_time: float = 0.0
    intensities: np.ndarray = field(default_factory=lambda: np.zeros(0, np.float32))


# how many beams len(ranges) may differ from what the angles imply (see scan_to_points)
MAX_BEAM_MISMATCH = 2.01


def stamp_ns(scan) -> int:
    """Header stamp in integer nanoseconds."""
    st = scan.header.stamp
    return int(st.sec) * 1_000_000_000 + int(st.nanosec)


def frame_of(scan) -> str:
    """``header.frame_id`` or an empty string."""
    return str(getattr(scan.header, 'frame_id', '') or '')


@dataclass(frozen=True)
class ScanPoints:
    """
    One scan in the filter's terms.

    Attributes
    ----------
    points : (m, 2) array
        Valid returns in the scan frame (x forward, y left), m.
    beam : (m,) int array
        Index of the beam of each point in the message.
    angles : (B,) array
        Angle of every beam (rad), in message order.
    ranges : (B,) array
        Every range as float, ``inf`` where the beam is invalid (no return).
    valid : (B,) bool array
    masked : dict
        Count of invalid beams of each kind in :data:`INVALID_KINDS`.
    angle_lo, angle_hi : float
        Field of view (rad), ``angle_lo <= angle_hi`` whatever the increment's sign.
    range_max : float
        Effective maximum range (m).

    """

    points: np.ndarray
    beam: np.ndarray
    angles: np.ndarray
    ranges: np.ndarray
    valid: np.ndarray
    masked: dict
    angle_lo: float
    angle_hi: float
    range_max: float

    @property
    def fov(self) -> float:
        """Angle the beams cover (rad), each beam counting its own spacing."""
        return min(self.angle_hi - self.angle_lo + abs(self.angle_step), 2 * math.pi)

    @property
    def area(self) -> float:
        """Area of the field-of-view sector (m^2): where clutter and births can appear."""
        return max(0.5 * self.fov * self.range_max ** 2, 1e-6)

    def beam_clutter_log_density(self, points: np.ndarray) -> np.ndarray:
        """
        ``log c(z)`` at each of ``points`` for clutter that falls on a beam drawn uniformly
        at a range drawn uniformly in ``[0, range_max]``: ``c(z) = 1 / (fov range_max r)``
        in Cartesian coordinates (the polar area element is ``r dr dtheta``), with ``r``
        at least :data:`BEAM_CLUTTER_MIN_RANGE` (so it integrates over the sector to
        ``1 - BEAM_CLUTTER_MIN_RANGE / (2 range_max)``, not quite 1).

        A laser's spurious returns (dust, rain, mixed pixels) come per beam, so they are
        ``range_max / r`` times denser at range ``r`` than clutter spread evenly over the
        sector; taken as even, the returns near the scanner looked like an object there.
        """
        r = np.sqrt(np.sum(points * points, axis=1))
        return -np.log(max(self.fov, 1e-9) * max(self.range_max, 1e-6)
                       * np.maximum(r, BEAM_CLUTTER_MIN_RANGE))

    @property
    def angle_step(self) -> float:
        """Absolute angular spacing of the beams (rad)."""
        if len(self.angles) > 1:
            return abs(float(self.angles[1] - self.angles[0]))
        return 0.0

    @cached_property
    def sorted_beams(self) -> tuple[np.ndarray, np.ndarray, float]:
        """
        ``(order, angles[order], median spacing)``: the beams by ascending angle, computed
        once per scan for the p_D model's interval lookups.
        """
        order = self.angles.argsort(kind='stable')
        ang = self.angles[order]
        return order, ang, median_of(ang[1:] - ang[:-1]) if len(ang) > 1 else 0.0

    @cached_property
    def sorted_ranges(self) -> np.ndarray:
        """``ranges`` in the order of :attr:`sorted_beams` (the p_D model reads them twice
        a scan)."""
        return self.ranges[self.sorted_beams[0]]

    @cached_property
    def full_turn(self) -> bool:
        """The beams go all the way round (a 360 degree scanner): no edge of the field of
        view, the last beam next to the first."""
        step = self.angle_step
        return step > 0 and self.angle_hi - self.angle_lo + 1.5 * step >= 2 * math.pi

    @cached_property
    def wrapped_beams(self) -> tuple[np.ndarray, np.ndarray]:
        """
        ``(order, angles)`` of :attr:`sorted_beams` with half a turn of beams repeated
        2 pi below and above, for a :attr:`full_turn` scan: an interval across the seam
        finds its beams on both sides.
        """
        order, ang, _ = self.sorted_beams
        half = len(ang) // 2
        return (np.concatenate([order[-half:], order, order[:half]]),
                np.concatenate([ang[-half:] - 2 * math.pi, ang, ang[:half] + 2 * math.pi]))

    def in_scan_frame(self, bearing: np.ndarray) -> np.ndarray:
        """
        Bearings (``arctan2``, in (-pi, pi]) moved by whole turns to lie nearest the middle
        of the field of view, where the beam angles are: a scanner reporting 0 to 2 pi
        (some 360 degree drivers do) has the beam of bearing -pi/2 at 3 pi/2. Unchanged,
        bit for bit, where no turn is needed.
        """
        x = (0.5 * (self.angle_lo + self.angle_hi) - bearing) / (2 * math.pi)
        # no turn rounds to anything but 0 (halves round to even, so |x| <= 1/2 is none)
        if np.max(np.abs(x), axis=None, initial=0.0) <= 0.5:
            return bearing
        return bearing + (2 * math.pi) * np.round(x)


def median_of(x: np.ndarray) -> float:
    """``np.median`` of a 1-D array (the same value) without its dispatch: the mean of the
    middle one or two order statistics."""
    k = len(x)
    lo, hi = (k - 1) // 2, k // 2
    part = np.partition(x, (lo, hi))
    return float((part[lo] + part[hi]) / 2)


def _finite(name, value):
    try:
        value = float(value)
    except (TypeError, ValueError) as err:
        msg = f'{name} must be a number, got {value!r}'
        raise ScanError(msg) from err
    if not math.isfinite(value):
        raise ScanError(f'{name} must be finite, got {value!r}')
    return value


def scan_to_points(scan, min_range: float = 0.0, max_range: float = 0.0,
                   range_max_inclusive: bool = False) -> ScanPoints:
    """
    Convert one scan, masking invalid beams.

    Parameters
    ----------
    scan : LaserScan-like
    min_range, max_range : float
        Extra limits (m) on top of the scan's own; ``max_range = 0`` means none.
    range_max_inclusive : bool
        Keep returns exactly at ``range_max`` (many drivers report "no return" there).

    Raises
    ------
    ScanError
        On a malformed scan: non-finite or zero angle increment, non-finite angles or range
        limits, ``range_max <= range_min``, a field of view beyond a full turn, or
        ``len(ranges)`` disagreeing with ``angle_min``/``angle_max``/``angle_increment`` by
        more than two beams (a truncated or garbled scan).

    Notes
    -----
    Invalid beams: NaN, +inf, -inf, below ``range_min``, above ``range_max``, each beam
    counted under one kind. A scan with no valid beam converts to zero points: the caller
    runs a predict-only step. An empty ``ranges`` under angle fields that declare beams is
    malformed like any other disagreement (a truncated message), where an all-NaN scan is
    data.

    """
    a0, inc, r_lo, r_hi, ranges = _checked_fields(scan)
    n = len(ranges)
    if min_range > 0:
        r_lo = max(r_lo, min_range)
    if max_range > 0:
        r_hi = min(r_hi, max_range)
    angles = a0 + inc * np.arange(n)
    valid, masked = _classify_beams(ranges, r_lo, r_hi, range_max_inclusive)
    beam = valid.nonzero()[0]
    r = ranges[beam]
    th = angles[beam]
    points = np.empty((len(beam), 2))
    np.multiply(r, np.cos(th), out=points[:, 0])
    np.multiply(r, np.sin(th), out=points[:, 1])
    clean = np.where(valid, ranges, np.inf)
    if n:
        lo, hi = float(min(angles[0], angles[-1])), float(max(angles[0], angles[-1]))
    else:
        lo = hi = a0
    return ScanPoints(points, beam, angles, clean, valid, masked, lo, hi, r_hi)


def _checked_fields(scan):
    """``(angle_min, angle_increment, range_min, range_max, ranges)`` of a scan, checked
    (see :func:`scan_to_points` for what raises)."""
    a0 = _finite('angle_min', scan.angle_min)
    inc = _finite('angle_increment', scan.angle_increment)
    r_lo = _finite('range_min', scan.range_min)
    r_hi = _finite('range_max', scan.range_max)
    if inc == 0.0:
        raise ScanError('angle_increment must not be zero')
    if r_lo < 0 or r_hi <= r_lo:
        raise ScanError(f'range limits must satisfy 0 <= range_min < range_max, got '
                        f'range_min={r_lo}, range_max={r_hi}')
    try:
        ranges = np.asarray(scan.ranges, dtype=float).ravel()
    except (TypeError, ValueError) as err:
        msg = f'ranges must be numbers: {err}'
        raise ScanError(msg) from err
    n = len(ranges)
    if n * abs(inc) > 2 * math.pi + abs(inc) + 1e-6:
        raise ScanError(f'{n} beams of {inc:.6g} rad span more than a full turn')
    a_max = getattr(scan, 'angle_max', None)
    if a_max is not None:
        a1 = _finite('angle_max', a_max)
        expected = (a1 - a0) / inc + 1.0
        # Drivers differ by a beam in two conventions: angle_max as n rather than n - 1
        # increments from angle_min, and angles at beam edges rather than centres. The beam
        # angles are angle_min + k * angle_increment whatever angle_max says, so up to two
        # beams (and float32 rounding) are taken; the Freiburg SICK recording's
        # /ROBOTLASER1 is 1.015 beams off, and all of its scans were refused.
        # an empty ranges array under angle fields that declare beams is a truncated
        # message too, not a scan that saw nothing (that one has its beams, all invalid)
        if (n and expected < 0.5) or abs(expected - n) > MAX_BEAM_MISMATCH:
            raise ScanError(f'len(ranges) = {n} disagrees with angle_min={a0:.6g}, '
                            f'angle_max={a1:.6g}, angle_increment={inc:.6g} '
                            f'(expected {expected:.1f} beams)')
    return a0, inc, r_lo, r_hi, ranges


def _classify_beams(ranges: np.ndarray, r_lo: float, r_hi: float, range_max_inclusive: bool):
    """The valid beams (a mask) and the count of each invalid kind, each beam counted
    under one kind."""
    finite = np.isfinite(ranges)
    is_nan = np.isnan(ranges)
    inf = ~(finite | is_nan)
    neg_inf = inf & np.signbit(ranges)
    pos_inf = inf ^ neg_inf
    # comparisons on the finite ranges only: a NaN compared raises the invalid flag
    fin = np.where(finite, ranges, r_lo)
    below = fin < r_lo
    above = (fin > r_hi) if range_max_inclusive else (fin >= r_hi)
    above &= finite
    # limits that leave no range between them (a configured min_range beyond range_max):
    # a return at or beyond range_max counts as above_max only, so each beam counts once
    below &= ~above
    valid = finite & ~below & ~above
    masked = {'nan': int(np.count_nonzero(is_nan)), 'pos_inf': int(np.count_nonzero(pos_inf)),
              'neg_inf': int(np.count_nonzero(neg_inf)),
              'below_min': int(np.count_nonzero(below)),
              'above_max': int(np.count_nonzero(above))}
    return valid, masked
