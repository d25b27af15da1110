"""
The filter update builds the ET-CPHD (and ET-PHD) update's inputs as the model note defines
them, and reads its posterior back per label.

Oracle: ``cphd_update`` / ``phd_update`` (each checked against enumeration in
test_cphd_bruteforce) called with inputs written out here from their definitions: the
predicted weights and the birth intensity ``birth.rate * dt`` (at 10 and 40 Hz); the
miss factors ``1 - p_D (1 - (beta / (beta + 1))^alpha)``, the birth's at ``p_D0`` with its
prior Gamma; ``log g = log p_D + log l`` for each gated (component, cell) pair and
``log p_D0 + log l`` for the birth row (cells of at least ``birth.min_points``);
``log c^W = -|W| log A``; the clutter cardinality Poisson(``clutter_rate``). The scene's
partitions are known: two lone returns far apart, each by a label that may have made it
or clutter, and a tight cluster of three that only a birth or clutter explains, taken
whole and as lone returns (``split_small`` 3; partitioning's other extras off). Each
label's posterior weight (missed plus detected, what the merge within a label keeps,
plus the births on the cells it claims), the new labels' total and the posterior
cardinality must be the oracle's.
"""

import numpy as np
import pytest

from extended_tracker.config import from_dict
from extended_tracker.filter.births import birth_prior
from extended_tracker.filter.cardinality import poisson_log_pmf
from extended_tracker.filter.cphd import cphd_update, phd_update
from extended_tracker.filter.ggiw import cell_stats, log_miss_factor, update_pairs
from extended_tracker.filter.mixture import IW_OFFSET, Mixture
from extended_tracker.filter.state import FilterState
from extended_tracker.filter.update import sensor_noise, SensorTerms
from extended_tracker.tracker import TrackerState, update_step

from mixtures import reported, with_fields

AREA = 150.0
DT = 0.1


def scene(mode):
    cfg = from_dict({
        'model': {'mode': mode},
        'partition': {'split_small': 3, 'sub_partition': False,
                      'prediction_partition': False},
        'reduction': {'prune_weight': 1e-12},
        'birth': {'min_weight': 0.0},
    })
    # three labels: one by each lone return, one with nothing near it (missed)
    centres = np.array([[3.0, 0.0], [3.0, 3.0], [5.0, -3.0]])
    k = len(centres)
    P = np.tile(np.diag([0.05 ** 2, 0.05 ** 2, 0.2, 0.2]), (k, 1, 1))
    v = np.full(k, 30.0)
    V = (v - IW_OFFSET)[:, None, None] * (0.2 ** 2 * np.eye(2))
    mix = Mixture(np.array([0.9, 0.7, 0.8]), np.array([20.0, 15.0, 12.0]),
                  np.array([2.0, 2.5, 1.5]), np.column_stack([centres, np.zeros((k, 2))]),
                  P, v, V, np.array([1, 2, 3]))
    # the predicted cardinality: near the weights' sum and the birth's (not Poisson)
    log_card = -0.5 * (np.arange(cfg.model.n_max + 1) - 2.5) ** 2 / 0.8
    state = TrackerState(FilterState(mix, log_card - np.logaddexp.reduce(log_card), 4))
    points = np.array([[3.05, 0.1], [2.95, 3.12],                   # the lone returns
                       [6.0, 1.96], [6.03, 2.0], [6.0, 2.04]])       # within d_min
    cells = [np.array([0]), np.array([1]), np.arange(2, 5), np.array([2]), np.array([3]),
             np.array([4])]
    return cfg, state, points, cells, [np.arange(3), np.array([0, 1, 3, 4, 5])]


def run_update(state, points, p_d, cfg, dt=DT, **sensor):
    """The update of the scene's prediction ``state.filter`` with ``points``, the given
    p_D and ``sensor`` terms (``SensorTerms`` fields), births spread over ``AREA``."""
    return update_step(state, state.filter, points, SensorTerms(p_d, **sensor), cfg, dt, AREA)


@pytest.mark.parametrize('mode', ['cphd', 'phd'])
@pytest.mark.parametrize('dt', [DT, 0.025])                  # 10 Hz, and a 40 Hz scanner
def test_the_update_builds_its_inputs_as_defined(mode, dt):
    cfg, state, points, cells, partitions = scene(mode)
    mix, mc, b = state.filter.mixture, cfg.model, cfg.birth
    p_d = np.array([0.9, 0.5, 0.7])
    got, _, diag = run_update(state, points, p_d, cfg, dt)
    assert diag.partitions == 2 and diag.cells == 6

    # the oracle's inputs; pairs: each of the first two labels with its own cluster
    st = cell_stats(points, cells)
    R = sensor_noise(cfg)
    pair = update_pairs(mix, np.array([0, 1]), st, np.array([0, 1]), mc.rho, R)
    births = birth_prior(st, cfg, AREA)
    born = update_pairs(births, np.arange(6), st, np.arange(6), mc.rho, R)
    log_g = np.full((4, 6), -np.inf)
    log_g[[0, 1], [0, 1]] = np.log(p_d[:2]) + pair.log_lik
    log_g[3] = np.where(st.n >= b.min_points, np.log(cfg.detection.p_d0) + born.log_lik,
                        -np.inf)
    beta_b = b.rate_shape / b.expected_rate
    birth_qd = np.log(1 - cfg.detection.p_d0
                      * (1 - (beta_b / (beta_b + 1)) ** b.rate_shape))
    log_w = np.log(np.append(mix.w, b.rate * dt))
    log_qd = np.append(log_miss_factor(mix, p_d), birth_qd)
    log_c = -st.n * np.log(AREA)
    if mode == 'cphd':
        want = cphd_update(log_w, log_qd, log_g, log_c, st.n, partitions, state.filter.log_card,
                           poisson_log_pmf(mc.clutter_rate, len(points) + 1))
        np.testing.assert_allclose(np.exp(got.filter.log_card), np.exp(want.log_card),
                                   rtol=1e-9, atol=1e-15)
    else:
        want = phd_update(log_w, log_qd, log_g, log_c, st.n, partitions, mc.clutter_rate,
                          mc.n_max)
    det = np.exp(want.log_w_detected)
    expected = np.exp(want.log_w_missed[:3]) + det[:3].sum(axis=1)
    # a birth on a cell a label explains with more weight is that object restarted: it
    # takes the label (tracker.label_births); the others are new labels
    claimed = det[:3].max(axis=0) > det[3]
    np.add.at(expected, det[:3].argmax(axis=0)[claimed], det[3][claimed])
    post = got.filter.mixture
    for i, label in enumerate([1, 2, 3]):
        assert post.w[post.label == label].sum() == pytest.approx(expected[i], rel=1e-9)
    assert post.w[post.label >= 4].sum() == pytest.approx(det[3][~claimed].sum(), rel=1e-9)
    # the scene exercises what it is for: a detected, a half-detected and a missed label,
    # and a birth with weight
    assert expected[0] > 0.5 and det[3][~claimed].sum() > 0.1 and claimed[:2].all()


def test_the_birth_miss_factor_uses_the_birth_gamma_of_mean_expected_rate():
    """The birth intensity's log q_D is 1 - p_D0 (1 - E[e^-gamma]) under the birth prior's
    Gamma: shape birth.rate_shape, mean birth.expected_rate (rate beta = shape / mean),
    for which E[e^-gamma] = (beta / (beta + 1))^shape. With the default shape of 1 a rate
    of 1 / mean gave the same; at shape 2.5 it does not. Oracle: the same expectation by
    quadrature over scipy's Gamma."""
    from scipy import integrate, stats

    from extended_tracker.filter.births import birth_log_miss_factor

    cfg = from_dict({'birth': {'rate_shape': 2.5, 'expected_rate': 8.0},
                     'detection': {'p_d0': 0.9}})
    gamma = stats.gamma(2.5, scale=8.0 / 2.5)
    e0 = integrate.quad(lambda g: np.exp(-g) * gamma.pdf(g), 0, np.inf, epsabs=1e-14)[0]
    assert birth_log_miss_factor(cfg) == pytest.approx(np.log(1 - 0.9 * (1 - e0)),
                                                        rel=1e-10)


def test_a_birth_row_is_the_birth_prior_at_the_cell_with_the_uniform_density():
    """One row per cell, written out from the definition (``birth_prior``'s notes): at
    the cell's mean, at rest, position variance ``A / (2 pi)`` (a Gaussian whose density at
    its centre is the uniform ``1 / A``), velocity variance ``birth.velocity_std^2``, the
    Gamma and inverse Wishart of the birth prior (extent mean the floor semi-axis
    circle), weight 1, no label yet."""
    cfg = from_dict({'birth': {'velocity_std': 1.5, 'dof': 9.0, 'extent_semi_axis': 0.2,
                               'rate_shape': 2.0, 'expected_rate': 8.0}})
    points = np.array([[3.0, 0.0], [3.1, 0.1], [6.0, 2.0]])
    st = cell_stats(points, [np.array([0, 1]), np.array([2])])
    born = birth_prior(st, cfg, AREA)
    np.testing.assert_allclose(born.m, [[3.05, 0.05, 0, 0], [6.0, 2.0, 0, 0]], rtol=1e-12)
    P = np.diag([AREA / (2 * np.pi)] * 2 + [1.5 ** 2] * 2)
    np.testing.assert_allclose(born.P, [P, P], rtol=1e-12)
    assert born.v.tolist() == [9.0, 9.0]
    np.testing.assert_allclose(born.V, [(9.0 - IW_OFFSET) * 0.04 * np.eye(2)] * 2, rtol=1e-12)
    assert born.alpha.tolist() == [2.0, 2.0] and born.beta.tolist() == [0.25, 0.25]
    assert born.w.tolist() == [1.0, 1.0] and born.label.tolist() == [0, 0]


def test_a_rate_scale_of_zero_counts_as_a_thousandth():
    """A component none of whose extent is in view (rate scale 0) expects a thousandth
    of its returns, not none: the update stays finite, as at 1e-3."""
    cfg, state, points, _, _ = scene('cphd')
    p_d = np.array([0.9, 0.5, 0.7])
    zero = run_update(state, points, p_d, cfg, rate_scale=np.zeros(3))[0].filter
    tiny = run_update(state, points, p_d, cfg, rate_scale=np.full(3, 1e-3))[0].filter
    assert np.isfinite(zero.mixture.w).all() and np.isfinite(zero.log_card).any()
    np.testing.assert_array_equal(zero.mixture.w, tiny.mixture.w)
    np.testing.assert_array_equal(zero.log_card, tiny.log_card)


def test_a_labels_visible_fraction_is_its_heaviest_components():
    """Label 1 predicted as two components, a light one (0.1) listed first: its report
    carries the visible fraction of the heavy one, the part it is reported by, not of
    whichever comes first."""
    cfg, state, points, _, _ = scene('cphd')
    mix = state.filter.mixture
    first = mix.take(np.array([0]))
    light = Mixture(np.array([0.1]), first.alpha, first.beta, first.m + [0.05, 0, 0, 0],
                    first.P, first.v, first.V, first.label)
    labels = np.array([1, 2, 3])
    state = with_fields(state, mixture=Mixture.concat([light, mix]), shown=labels,
                        shown_pos=mix.m[:, :2].copy(), shown_vel=np.zeros((3, 2)),
                        shown_elapsed=np.zeros(3))
    # and confirmed
    state = TrackerState(state.filter, reported(state.tracks, labels, [9, 9, 9], mix.m[:, :2],
                                                size=0.2))
    _, est, _ = run_update(state, points, np.array([0.9, 0.9, 0.5, 0.7]), cfg,
                           visibility=np.array([0.2, 0.95, 0.5, 0.6]))
    assert est.label.tolist() == [1, 2] and est.visibility.tolist() == [0.95, 0.5]


def test_birth_hypotheses_lighter_than_birth_min_weight_are_dropped():
    """The scene's birth on the cluster (weight over 0.1) is a new label; with
    ``birth.min_weight`` 1 no birth hypothesis is kept, whatever the prune weight."""
    from dataclasses import replace

    cfg, state, points, _, _ = scene('cphd')
    p_d = np.array([0.9, 0.5, 0.7])
    got, _, diag = run_update(state, points, p_d, cfg)
    assert (got.filter.mixture.label >= 4).any() and diag.births >= 1
    strict = replace(cfg, birth=replace(cfg.birth, min_weight=1.0))
    got, _, diag = run_update(state, points, p_d, strict)
    assert not (got.filter.mixture.label >= 4).any() and diag.births == 0


def test_the_births_a_sensor_can_refuse_are_those_no_seen_pair_explains():
    """``Pairs.free_birth_cells``: the cells of at least ``birth.min_points`` returns that
    no pair with p_D above zero explains. In the scene the two lone returns are paired
    with labels 1 and 2; with the pair of label 2 unseen (p_D 0) its cell is free too."""
    from extended_tracker.filter.update import pair_updates

    cfg, state, points, _, _ = scene('cphd')
    mix = state.filter.mixture
    pairs = pair_updates(mix, points, cfg, SensorTerms(np.full(3, 0.9)), AREA)
    seen = np.full(len(pairs.comp), 0.9)
    free = pairs.free_birth_cells(seen, 1)
    paired = set(pairs.cell.tolist())
    assert set(free.tolist()) == set(range(pairs.n_cells)) - paired
    by_two = pairs.cell[pairs.comp == 1]
    seen[pairs.comp == 1] = 0.0
    assert set(pairs.free_birth_cells(seen, 1).tolist()) == set(free.tolist()) | set(
        by_two.tolist()) - set(pairs.cell[pairs.comp != 1].tolist())
    # a cell smaller than min_points is never a birth to refuse
    assert all(pairs.stats.n[c] >= 3 for c in pairs.free_birth_cells(seen, 3))
