"""Scan conversion against hand-computed scans; every invalid-beam kind; malformed scans."""

import math

from hypothesis import given, strategies as st
import numpy as np
import pytest

from extended_tracker.errors import ScanError
from extended_tracker.sensing.scan import Header, scan_to_points, ScanData, Stamp


def make_scan(ranges, angle_min=-math.pi / 2, inc=math.pi / 2, range_min=0.1, range_max=10.0,
              angle_max=None):
    ranges = np.asarray(ranges, dtype=float)
    if angle_max is None:
        angle_max = angle_min + inc * (len(ranges) - 1)
    return ScanData(Header(Stamp(1, 0), 'laser'), angle_min, angle_max, inc, range_min,
                    range_max, ranges)


def test_hand_computed_points():
    # beams at -90, 0, +90 degrees: right, forward, left
    sp = scan_to_points(make_scan([1.0, 2.0, 3.0]))
    np.testing.assert_allclose(sp.points, [[0.0, -1.0], [2.0, 0.0], [0.0, 3.0]], atol=1e-12)
    assert sp.beam.tolist() == [0, 1, 2]
    assert sum(sp.masked.values()) == 0


def test_every_invalid_kind_is_masked_and_counted():
    ranges = [np.nan, np.inf, -np.inf, 0.05, 12.0, 10.0, 5.0, np.inf]
    sp = scan_to_points(make_scan(ranges, angle_min=0.0, inc=0.1))
    assert sp.masked == {'nan': 1, 'pos_inf': 2, 'neg_inf': 1, 'below_min': 1, 'above_max': 2}
    assert sp.beam.tolist() == [6]                    # range_max itself means "no return"
    np.testing.assert_allclose(sp.points, [[5 * math.cos(0.6), 5 * math.sin(0.6)]])
    inclusive = scan_to_points(make_scan(ranges, angle_min=0.0, inc=0.1),
                               range_max_inclusive=True)
    assert inclusive.beam.tolist() == [5, 6] and inclusive.masked['above_max'] == 1
    # every beam without a valid return has no range (inf: nothing in front of the
    # scanner there, for the p_D model), whatever its kind
    assert np.isinf(sp.ranges).tolist() == [True] * 6 + [False, True]
    assert sp.ranges[6] == 5.0 and sp.valid.tolist() == [False] * 6 + [True, False]


def test_configured_range_limits_tighten_the_scans_own():
    """scan.min_range / scan.max_range narrow the scan's range_min / range_max (never
    widen them); the beams they drop count as below_min / above_max."""
    ranges = [0.05, 0.3, 1.0, 4.0, 6.0, 9.5]          # scan limits 0.1 .. 10 m
    sp = scan_to_points(make_scan(ranges, angle_min=0.0, inc=0.1), min_range=0.5,
                        max_range=5.0)
    assert sp.beam.tolist() == [2, 3]
    assert sp.masked['below_min'] == 2 and sp.masked['above_max'] == 2
    assert sp.range_max == 5.0                         # the range clutter spreads over
    loose = scan_to_points(make_scan(ranges, angle_min=0.0, inc=0.1), min_range=0.01,
                           max_range=50.0)
    assert loose.beam.tolist() == [1, 2, 3, 4, 5]      # the scan's own 0.1 m still holds
    assert loose.range_max == 10.0                     # and its own 10 m
    # limits that leave no range between them (min_range beyond the scan's range_max):
    # every beam is invalid, a NaN counted as nan and not also as above_max
    none_left = scan_to_points(make_scan(ranges + [np.nan, np.inf], angle_min=0.0, inc=0.1),
                               min_range=12.0)
    assert len(none_left.beam) == 0
    assert none_left.masked == {'nan': 1, 'pos_inf': 1, 'neg_inf': 0, 'below_min': 6,
                                'above_max': 0}
    # a return between the two (beyond the scan's 10 m, short of the 12 m asked for) is
    # the driver's "no return": counted once, as above_max, so the counts add up to the
    # beams
    between = scan_to_points(make_scan([11.0, 3.0, np.nan], angle_min=0.0, inc=0.1),
                             min_range=12.0)
    assert between.masked == {'nan': 1, 'pos_inf': 0, 'neg_inf': 0, 'below_min': 1,
                              'above_max': 1}


def test_zero_ranges_of_drivers_count_below_min():
    sp = scan_to_points(make_scan([0.0, 0.0, 2.0], range_min=0.02))
    assert sp.masked['below_min'] == 2 and len(sp.points) == 1


def test_negative_increment():
    # +135 deg down to -135 deg, as a scanner mounted upside down reports
    inc = -math.pi / 2
    sp = scan_to_points(make_scan([1.0, 1.0, 1.0, 1.0], angle_min=3 * math.pi / 4, inc=inc,
                                  angle_max=-3 * math.pi / 4))
    expected = [[math.cos(a), math.sin(a)] for a in (3 * math.pi / 4, math.pi / 4,
                                                     -math.pi / 4, -3 * math.pi / 4)]
    np.testing.assert_allclose(sp.points, expected, atol=1e-12)
    assert sp.angle_lo == pytest.approx(-3 * math.pi / 4)
    assert sp.angle_hi == pytest.approx(3 * math.pi / 4)
    # the beam spacing is a spacing, whatever the direction: 90 deg (and these four
    # beams, 90 deg apart across the back too, go all the way round), and a full turn
    # listed downwards is a full turn
    assert sp.angle_step == pytest.approx(math.pi / 2) and sp.full_turn
    inc = -math.radians(1.0)
    turn = scan_to_points(make_scan(np.ones(360), angle_min=math.pi, inc=inc))
    assert turn.angle_step == pytest.approx(math.radians(1.0)) and turn.full_turn


def test_empty_and_all_invalid_scans_give_no_points():
    empty = scan_to_points(make_scan([], angle_min=0.3))
    assert len(empty.points) == 0 and empty.angle_lo == empty.angle_hi == 0.3
    # but an empty ranges array under angle fields that declare 1081 beams is truncated
    with pytest.raises(ScanError, match='len.ranges. = 0 disagrees .* 1081.0 beams'):
        scan_to_points(make_scan([], angle_min=-2.356194, inc=0.004363323, angle_max=2.356194))
    sp = scan_to_points(make_scan([np.nan, np.inf, 0.0]))
    assert len(sp.points) == 0 and sum(sp.masked.values()) == 3


@pytest.mark.parametrize('kwargs, fragment', [
    ({'inc': 0.0}, 'angle_increment must not be zero'),
    ({'inc': float('nan')}, 'angle_increment must be finite'),
    ({'range_min': 5.0, 'range_max': 1.0}, 'range limits'),
    ({'range_min': 2.0, 'range_max': 2.0}, 'range limits'),     # no range left between
    ({'range_min': -0.1}, 'range limits'),
    ({'range_max': float('inf')}, 'range_max must be finite'),
    ({'angle_max': 5.0}, 'disagrees'),
    ({'range_min': 'near'}, 'range_min must be a number'),
    ({'range_max': [10.0]}, 'range_max must be a number'),
])
def test_malformed_scans_raise_clear_errors(kwargs, fragment):
    with pytest.raises(ScanError, match=fragment):
        scan_to_points(make_scan([1.0, 2.0, 3.0], **kwargs))


def test_angle_max_one_or_two_beams_off_is_taken():
    """angle_max n rather than n - 1 increments out, angles at beam edges, or both; and
    the float32 geometry of the Freiburg SICK recording's /ROBOTLASER1 (361 beams where
    the angles imply 359.985). The beams are where angle_min and the increment put them.
    Three beams off is a truncated scan, refused."""
    inc = 0.01
    for n, span in ((100, 99), (100, 100), (100, 101), (100, 98), (100, 97.02)):
        sp = scan_to_points(make_scan(np.ones(n), angle_min=0.0, inc=inc,
                                      angle_max=span * inc))
        np.testing.assert_allclose(sp.angles, inc * np.arange(n))
    f32 = np.float32
    sp = scan_to_points(make_scan(np.ones(361), angle_min=float(f32(-1.5664324760437012)),
                                  inc=float(f32(0.008727000094950199)),
                                  angle_max=float(f32(1.5664335489273071))))
    assert len(sp.points) == 361
    # exactly two beams off, in binary-exact figures: taken; angle_max behind angle_min
    # for the increment's direction (a single beam: 0.2 beams expected): refused
    assert len(scan_to_points(make_scan(np.ones(3), angle_min=0.0, inc=0.5,
                                        angle_max=2.0)).points) == 3
    with pytest.raises(ScanError, match='disagrees'):
        scan_to_points(make_scan([1.0], angle_min=0.0, inc=0.125, angle_max=-0.1))
    for span in (96, 102):
        with pytest.raises(ScanError, match='disagrees'):
            scan_to_points(make_scan(np.ones(100), angle_min=0.0, inc=inc,
                                     angle_max=span * inc))


def test_more_than_a_full_turn_is_refused():
    with pytest.raises(ScanError, match='full turn'):
        scan_to_points(make_scan(np.ones(100), angle_min=0.0, inc=0.1, angle_max=9.9))
    # at 1 degree: 361 beams (a full turn and the seam's beam twice) are taken, 362 not
    inc = math.radians(1.0)
    sp = scan_to_points(make_scan(np.ones(361), angle_min=0.0, inc=inc, range_max=13.0))
    assert len(sp.points) == 361
    # covering no more than the full turn: its area is the disc's
    assert sp.full_turn and sp.fov == pytest.approx(2 * math.pi, rel=1e-12)
    assert sp.area == pytest.approx(math.pi * 13.0 ** 2, rel=1e-12)
    with pytest.raises(ScanError, match='full turn'):
        scan_to_points(make_scan(np.ones(362), angle_min=0.0, inc=inc))


def test_the_sector_area_and_the_beam_clutter_density():
    """The field of view's area is the sector's, 1/2 fov range_max^2, each beam counting its
    own spacing; the per-beam clutter density integrates over the sector (polar area
    element r dr dtheta, by the midpoint rule) to 1 - r0 / (2 range_max), r0 the 0.1 m
    below which it is held."""
    inc = math.radians(0.5)
    sp = scan_to_points(make_scan(np.ones(361), angle_min=-math.pi / 2, inc=inc,
                                  range_max=13.0))
    fov = math.pi + inc
    assert sp.fov == pytest.approx(fov, rel=1e-12)
    assert sp.area == pytest.approx(0.5 * fov * 13.0 ** 2, rel=1e-12)
    n_r, n_t = 20_000, 7
    r = (np.arange(n_r) + 0.5) * (13.0 / n_r)
    t = -math.pi / 2 - inc / 2 + (np.arange(n_t) + 0.5) * (fov / n_t)
    rr, tt = np.meshgrid(r, t)
    pts = np.column_stack([(rr * np.cos(tt)).ravel(), (rr * np.sin(tt)).ravel()])
    c = np.exp(sp.beam_clutter_log_density(pts))
    total = np.sum(c * rr.ravel()) * (13.0 / n_r) * (fov / n_t)
    assert total == pytest.approx(1 - 0.1 / (2 * 13.0), abs=1e-6)


@pytest.mark.parametrize('density', ['area', 'beam'])
def test_a_one_beam_scan_has_a_finite_clutter_density(density):
    """One beam covers no angle (no spacing to count): the sector's area and the per-beam
    clutter density are held at their floors, finite, and the filter steps through such
    scans without a division by zero (warnings are errors here)."""
    import warnings

    from extended_tracker.config import from_dict
    from extended_tracker.pipeline import PipelineState, step

    sp = scan_to_points(make_scan([3.0], angle_min=0.3))
    assert sp.fov == 0.0 and sp.area > 0.0
    assert np.isfinite(sp.beam_clutter_log_density(sp.points)).all()
    cfg = from_dict({'model': {'clutter_density': density}, 'background': {'enabled': False}})
    state = PipelineState.initial(cfg)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        for k in range(5):
            scan = make_scan([3.0], angle_min=0.3)
            scan.header.stamp = Stamp(1, k * 100_000_000)
            state, res = step(state, scan, cfg)
    assert not np.isnan(state.filter.log_card).any() and res.diagnostics['detections'] == 1


def test_non_numeric_ranges_are_refused():
    scan = make_scan([1.0, 2.0, 3.0])
    scan.ranges = ['a', 'b', 'c']
    with pytest.raises(ScanError, match='ranges must be numbers'):
        scan_to_points(scan)


@given(st.lists(st.floats(0.2, 30.0), min_size=1, max_size=200),
       st.floats(-math.pi, math.pi), st.floats(0.001, 0.05), st.booleans())
def test_polar_cartesian_polar_round_trip(ranges, a0, inc, negative):
    inc = -inc if negative else inc
    sp = scan_to_points(make_scan(ranges, angle_min=a0, inc=inc, range_min=0.1,
                                  range_max=31.0))
    r = np.hypot(sp.points[:, 0], sp.points[:, 1])
    th = np.arctan2(sp.points[:, 1], sp.points[:, 0])
    np.testing.assert_allclose(r, np.asarray(ranges)[sp.beam], rtol=1e-12)
    # angles compared on the circle
    d = np.angle(np.exp(1j * (th - sp.angles[sp.beam])))
    assert np.max(np.abs(d)) < 1e-9


def test_median_helper_equals_numpy_median():
    from extended_tracker.sensing.scan import median_of

    rng = np.random.default_rng(0)
    for n in list(range(1, 12)) + [360, 1080]:
        for _ in range(20):
            x = rng.normal(0, 1, n) * 10.0 ** rng.integers(-8, 8)
            assert median_of(x) == float(np.median(x))
