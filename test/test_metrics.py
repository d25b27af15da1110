"""GOSPA with the Gaussian-Wasserstein distance: metric axioms and hand-computed cases."""

from hypothesis import given, strategies as st
import numpy as np
import pytest
from scipy.linalg import sqrtm

from extended_tracker.evaluation.metrics import gospa, gw_distance, score_sequence


def spd(rng, k):
    B = rng.normal(0, 0.4, (k, 2, 2))
    return B @ np.swapaxes(B, 1, 2) + 0.01 * np.eye(2)


def test_gw_distance_against_general_sqrtm():
    rng = np.random.default_rng(0)
    m1, m2 = rng.normal(size=(3, 2)), rng.normal(size=(4, 2))
    X1, X2 = spd(rng, 3), spd(rng, 4)
    d = gw_distance(m1, X1, m2, X2)
    for i in range(3):
        for j in range(4):
            r = np.real(sqrtm(X1[i]))
            tr = np.trace(X1[i] + X2[j] - 2 * np.real(sqrtm(r @ X2[j] @ r)))
            assert d[i, j] == pytest.approx(np.sqrt(np.sum((m1[i] - m2[j]) ** 2) + tr),
                                            rel=1e-9)


def test_hand_computed_cases():
    I = np.eye(2)[None]
    # same extent: the distance is the centre distance
    assert gw_distance([[0, 0]], 0.04 * I, [[3, 4]], 0.04 * I)[0, 0] == pytest.approx(5.0)
    # same centre, circles of radius 0.2 and 0.5: tr(X1 + X2 - 2 sqrt(X1 X2)) = 2 * 0.3^2
    assert gw_distance([[0, 0]], 0.04 * I, [[0, 0]], 0.25 * I)[0, 0] == \
        pytest.approx(np.sqrt(2 * 0.09))
    # one truth, no estimate, c = 2, p = 2: (c^p / 2)^(1/p) = sqrt(2)
    g = gospa(np.zeros((1, 2)), 0.04 * I, np.zeros((0, 2)), np.zeros((0, 2, 2)))
    assert g.total == pytest.approx(np.sqrt(2)) and g.n_missed == 1
    # a pair 0.3 m apart and one false estimate 10 m away: sqrt(0.3^2 + 2)
    g = gospa(np.array([[0.0, 0.0]]), 0.04 * I, np.array([[0.3, 0.0], [10.0, 0.0]]),
              np.concatenate([0.04 * I, 0.04 * I]))
    assert g.total == pytest.approx(np.sqrt(0.09 + 2.0))
    assert (g.n_missed, g.n_false) == (0, 1) and g.localisation == pytest.approx(0.09)
    # beyond the cut-off a pair counts as one missed and one false, not as a cut distance
    g = gospa(np.array([[0.0, 0.0]]), 0.04 * I, np.array([[5.0, 0.0]]), 0.04 * I)
    assert (g.n_missed, g.n_false) == (1, 1) and g.total == pytest.approx(2.0)
    # exactly at the cut-off (d = 2 = c; identity extents make it exact): either way the
    # pair costs c^p, and it is left unassigned (pairs are assigned only below c), so it
    # gives no id to the truth
    assert gw_distance([[0, 0]], I, [[2, 0]], I)[0, 0] == 2.0
    g = gospa(np.array([[0.0, 0.0]]), I, np.array([[2.0, 0.0]]), I)
    assert (g.n_missed, g.n_false, g.pairs) == (1, 1, ()) and g.total == pytest.approx(2.0)


@st.composite
def ellipse_sets(draw):
    n = draw(st.integers(0, 4))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    return rng.uniform(-3, 3, (n, 2)), spd(rng, n)


@given(ellipse_sets(), ellipse_sets(), ellipse_sets())
def test_gospa_is_a_metric(a, b, c):
    def d(x, y):
        return gospa(x[0], x[1], y[0], y[1]).total

    assert d(a, a) == pytest.approx(0.0, abs=1e-6)
    assert d(a, b) == pytest.approx(d(b, a), rel=1e-9, abs=1e-12)
    # triangle inequality (alpha = 2 makes GOSPA a metric); rounding slack 1e-9
    assert d(a, c) <= d(a, b) + d(b, c) + 1e-9


def test_id_switches_and_fragmentation():
    I = 0.04 * np.eye(2)[None]
    truth = [([7], np.array([[float(k), 0.0]]), I) for k in range(6)]
    est = [([1], np.array([[0.0, 0.0]]), I), ([1], np.array([[1.0, 0.0]]), I),
           ([], np.zeros((0, 2)), np.zeros((0, 2, 2))),           # lost: fragmentation
           ([2], np.array([[3.0, 0.0]]), I),                       # new label: a switch
           ([2], np.array([[4.0, 0.0]]), I), ([2], np.array([[5.0, 0.0]]), I)]
    score, per = score_sequence(truth, est)
    assert score.id_switches == 1 and score.fragmentations == 1
    assert score.cardinality_error == pytest.approx(1 / 6)
    assert per[2].n_missed == 1


def test_an_object_found_late_is_no_fragmentation():
    """A fragmentation is a track lost and found again: an object with no estimate in its
    first scans, then one label to the end, has none (and no switch)."""
    I = 0.04 * np.eye(2)[None]
    truth = [([3], np.array([[float(k), 0.0]]), I) for k in range(5)]
    none = ([], np.zeros((0, 2)), np.zeros((0, 2, 2)))
    est = [none, none] + [([8], np.array([[float(k), 0.0]]), I) for k in range(2, 5)]
    score, _ = score_sequence(truth, est)
    assert (score.fragmentations, score.id_switches) == (0, 0)
    assert score.cardinality_error == pytest.approx(2 / 5)


def test_hidden_objects_kept_are_counted_by_the_assignment():
    """
    Two objects over three scans; the first is hidden in scans 1 and 2 and has an
    estimate in scan 1 only, the second is in view with an estimate throughout: 2 hidden
    object-scans, 1 kept. An estimate too far to be assigned (over c) does not keep one.
    """
    I = 0.04 * np.eye(2)[None].repeat(2, axis=0)
    truth = [([1, 2], np.array([[0.0, 0.0], [5.0, 0.0]]), I) for _ in range(3)]
    both = np.array([[0.1, 0.0], [5.0, 0.1]])
    est = [([1, 2], both, I), ([1, 2], both, I),
           ([1, 2], np.array([[2.5, 0.0], [5.0, 0.1]]), I)]      # 2.5 m off: not assigned
    hidden = [np.array([False, False]), np.array([True, False]), np.array([True, False])]
    score, _ = score_sequence(truth, est, hidden_seq=hidden)
    assert (score.hidden, score.hidden_kept) == (2, 1)
    score, _ = score_sequence(truth, est)                        # not known: none counted
    assert (score.hidden, score.hidden_kept) == (0, 0)


def test_the_means_over_a_run_are_those_of_each_scans_parts():
    """
    Three scans: a pair 0.3 m apart (localisation 0.09), a missed object and a false
    estimate (c^p / 2 = 2 each). The run's means are those of the parts, by hand.
    """
    I = 0.04 * np.eye(2)[None]
    none = ([], np.zeros((0, 2)), np.zeros((0, 2, 2)))
    one = ([5], np.zeros((1, 2)), I)
    truth = [one, one, none]
    est = [([1], np.array([[0.3, 0.0]]), I), none, ([1], np.array([[4.0, 0.0]]), I)]
    score, per = score_sequence(truth, est)
    assert [g.total for g in per] == pytest.approx([0.3, np.sqrt(2), np.sqrt(2)])
    assert score.gospa_mean == pytest.approx((0.3 + 2 * np.sqrt(2)) / 3)
    assert score.localisation_mean == pytest.approx(0.09 / 3)
    assert score.missed_mean == pytest.approx(2 / 3)
    assert score.false_mean == pytest.approx(2 / 3)
    assert score.cardinality_error == pytest.approx(2 / 3)
    assert (score.scans, score.id_switches, score.fragmentations) == (3, 0, 0)
