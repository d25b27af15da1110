"""GGIW merging: the Gaussian and inverse Wishart moment matches against sampling, the
Gamma shape, the floor, and whose label a merge keeps."""

from dataclasses import replace as evolve

import numpy as np
import pytest
from scipy import stats

from extended_tracker.filter.mixture import IW_OFFSET, Mixture
from extended_tracker.filter.reduction import merge_groups, reduce_mixture

from mixtures import pedestrians

D = 2


def extent(major, minor, yaw):
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    return rot @ np.diag([major ** 2, minor ** 2]) @ rot.T


def mixture(w, v, X):
    """Components with weights ``w``, IW degrees ``v`` and expected extents ``X``."""
    k = len(w)
    v = np.asarray(v, dtype=float)
    V = (v - IW_OFFSET)[:, None, None] * np.asarray(X)
    return Mixture(np.asarray(w, dtype=float), np.full(k, 10.0), np.ones(k), np.zeros((k, 4)),
                   np.tile(0.01 * np.eye(4), (k, 1, 1)), v, V, np.zeros(k, dtype=np.int64))


def iw_samples(v, V, size, rng):
    # Koch's (v, V) is scipy's invwishart with df = v - d - 1 (test_ggiw checks it)
    return stats.invwishart(df=v - D - 1, scale=V).rvs(size=size, random_state=rng)


@pytest.mark.slow
def test_iw_merge_matches_the_mixture_moments_by_sampling():
    """The merged IW has the mixture's E[X^-1] and E[log|X|], both sides sampled."""
    rng = np.random.default_rng(7)
    w = np.array([0.5, 0.3, 0.2])
    X = [extent(0.3, 0.2, 0.1), extent(0.4, 0.15, 0.8), extent(0.25, 0.25, 0.0)]
    mix = mixture(w, [14.0, 20.0, 30.0], X)
    out = merge_groups(mix, [np.arange(3)])
    n = 200_000
    counts = rng.multinomial(n, w / w.sum())
    drawn = np.concatenate([iw_samples(mix.v[i], mix.V[i], c, rng)
                            for i, c in enumerate(counts)])
    merged = iw_samples(out.v[0], out.V[0], n, rng)
    # 2e5 draws: the sampled means are within ~0.5 % (E[X^-1]) and ~3e-3 (E[log|X|]) of
    # their expectations, so 2 % and 0.02 leave room for both sides' sampling error
    np.testing.assert_allclose(np.linalg.inv(merged).mean(axis=0),
                               np.linalg.inv(drawn).mean(axis=0), rtol=2e-2, atol=0.2)
    gap = np.linalg.slogdet(merged)[1].mean() - np.linalg.slogdet(drawn)[1].mean()
    assert abs(gap) < 0.02
    assert out.v[0] < mix.v.min()            # here the match is vaguer than every member


def test_gaussian_merge_matches_the_mixture_moments_by_sampling():
    """The merged kinematic Gaussian has the mixture's mean and covariance, the spread of
    the members' means included, against draws from the mixture; the merge keeps the
    heaviest member's label and the summed weight."""
    rng = np.random.default_rng(8)
    w = np.array([0.2, 0.5, 0.3])
    mix = mixture(w, [14.0, 20.0, 30.0], [extent(0.3, 0.2, 0.1)] * 3)
    m = np.array([[1.0, 2.0, 0.5, 0.0], [1.4, 1.8, 0.2, 0.3], [0.8, 2.3, 0.6, -0.1]])
    A = rng.normal(0, 0.2, (3, 4, 4))
    P = A @ A.swapaxes(1, 2) + 0.01 * np.eye(4)
    mix = Mixture(mix.w, mix.alpha, mix.beta, m, P, mix.v, mix.V, np.array([4, 9, 6]))
    out = merge_groups(mix, [np.arange(3)])
    n = 400_000
    counts = rng.multinomial(n, w / w.sum())
    drawn = np.concatenate([rng.multivariate_normal(m[i], P[i], c)
                            for i, c in enumerate(counts)])
    # 4e5 draws: the sample mean is within ~1e-3 and the covariance within ~3e-3 of
    # theirs (entries up to ~0.3), so 5e-3 and 1e-2 leave room
    np.testing.assert_allclose(out.m[0], drawn.mean(axis=0), atol=5e-3)
    np.testing.assert_allclose(out.P[0], np.cov(drawn.T), atol=1e-2)
    # without the spread of the means the covariance is short by some 0.07 on position
    within = np.einsum('i,ijk->jk', w / w.sum(), P)
    assert np.abs(out.P[0] - within).max() > 0.05
    assert out.label[0] == 9 and out.w[0] == pytest.approx(1.0)


def test_iw_merge_stays_finite_where_the_match_reaches_the_boundary():
    """
    Members of one pedestrian from a real replay (legtracker positive_1, scan 143): the
    unconstrained match put v at 6 + 2e-9, where E[X] = V / (v - 6) gave a 2 km semi-axis.
    The merged mean extent is held to twice the members' mean (trace), E[X^-1] still
    matched.
    """
    v = [6.25, 7.25, 8.25, 7.25, 9.25, 23.0]
    w = np.array([3.0, 0.29, 0.004, 0.004, 0.84, 0.16])
    majors = np.array([0.21, 0.33, 0.21, 0.10, 0.42, 0.33])
    yaws = [0.0, 1.2, 0.3, 2.0, 0.7, 1.5]
    mix = mixture(w, v, [extent(a, 0.3 * a, y) for a, y in zip(majors, yaws)])
    out = merge_groups(mix, [np.arange(6)])
    mean_x = np.einsum('k,kij->ij', w / w.sum(), mix.expected_extent())
    merged_x = out.V[0] / (out.v[0] - IW_OFFSET)
    assert np.trace(merged_x) == pytest.approx(2.0 * np.trace(mean_x), rel=1e-9)
    assert np.sqrt(np.linalg.eigvalsh(merged_x)[-1]) < 2 * majors.max()
    # E[X^-1] = (v - d - 1) V^-1 is still the mixture's
    inv_mean = np.einsum('k,kij->ij', w / w.sum(),
                         (mix.v - D - 1)[:, None, None] * np.linalg.inv(mix.V))
    np.testing.assert_allclose((out.v[0] - D - 1) * np.linalg.inv(out.V[0]), inv_mean,
                               rtol=1e-9)


def test_iw_merge_of_line_like_members_stays_bounded():
    """
    Two members of a wall segment from a MiR replay, their IW scales numerically rank one
    (eigenvalues 8e-16 and 1.06): the solve for nu ran to 4e27 with divide-by-zero warnings.
    Now nu stays in [floor, largest member] and the thin axis keeps MIN_SEMI_AXIS.
    """
    import warnings

    from extended_tracker.filter.reduction import MIN_SEMI_AXIS

    V = np.array([[[0.5069371854815066, -0.5277826890638175],
                   [-0.5277826890638175, 0.5494853698902643]],
                  [[0.5262614863738648, -0.5479016146682755],
                   [-0.5479016146682755, 0.570431595563959]]])
    v = np.array([108.1243804631815, 112.1243804631815])
    w = np.array([2.3891589955608454, 0.9999999733278248])
    mix = mixture(w, v, V / (v - IW_OFFSET)[:, None, None])
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        out = merge_groups(mix, [np.arange(2)])
    assert IW_OFFSET < out.v[0] <= v.max() + 1e-9
    minor = np.linalg.eigvalsh(out.V[0] / (out.v[0] - IW_OFFSET))[0]
    # the members' thin axis is far under a centimetre: the floor is what holds it
    assert minor == pytest.approx(MIN_SEMI_AXIS ** 2, rel=1e-6)


def test_nu_solver_matches_brentq_and_clamps_to_the_bracket():
    """
    ``solve_nu`` against scipy's brentq on the same scalar equation, entry by entry, with
    roots inside the bracket, at either end, beyond it, and brackets of zero width (equal
    members), all in one batch.
    """
    from scipy.optimize import brentq
    from scipy.special import digamma

    from extended_tracker.filter.reduction import solve_nu

    def f(nu, t):
        return 2 * np.log(nu) - digamma(0.5 * nu) - digamma(0.5 * nu - 0.5) - t

    rng = np.random.default_rng(7)
    k = 300
    lo = rng.uniform(3.0 + 1e-9, 6.0, k)
    hi = lo + rng.choice([0.0, 1e-9, 1.0, 50.0, 500.0], k)
    # targets from a nu inside, below or above the bracket
    nu_true = np.where(rng.random(k) < 0.6, rng.uniform(lo, hi),
                       np.where(rng.random(k) < 0.5, lo * 0.9, hi * 1.5 + 1))
    target = f(nu_true, 0.0)
    got = solve_nu(target, lo, hi, rng.uniform(lo, hi))
    for i in range(k):
        f_lo, f_hi = f(lo[i], target[i]), f(hi[i], target[i])
        if f_lo <= 0:
            want = lo[i]
        elif f_hi >= 0:
            want = hi[i]
        else:
            want = brentq(f, lo[i], hi[i], args=(target[i],), xtol=1e-14, rtol=1e-15)
        assert got[i] == pytest.approx(want, rel=1e-9)


def test_gamma_merge_solves_its_equation_to_rounding():
    """
    The merged shape ``a`` solves ``log a - digamma(a) = log E[g] - E[log g]``, the
    moments taken from the members with scipy: against brentq to 1e-12 relative, over
    200 groups of 2-4 distinct members (Newton stops at a relative step of 1e-10, one
    step after which the error is far below it; stopped at 1e-4 it was 1e-8).
    """
    from scipy.optimize import brentq
    from scipy.special import digamma

    rng = np.random.default_rng(1)
    for _ in range(200):
        k = int(rng.integers(2, 5))
        w, al, be = rng.uniform(0.1, 1, k), rng.uniform(0.5, 60, k), rng.uniform(0.2, 8, k)
        mix = evolve(mixture(w, [20.0] * k, [extent(0.3, 0.2, 0.0)] * k), alpha=al, beta=be)
        out = merge_groups(mix, [np.arange(k)])
        wn = w / w.sum()
        mean = np.sum(wn * al / be)
        c = np.log(mean) - np.sum(wn * (digamma(al) - np.log(be)))
        root = brentq(lambda a: np.log(a) - digamma(a) - c, 1e-12, 1e12, xtol=1e-300,
                      rtol=1e-15)
        assert out.alpha[0] == pytest.approx(root, rel=1e-12)
        assert out.alpha[0] / out.beta[0] == pytest.approx(mean, rel=1e-12)


@pytest.mark.parametrize('shape', [3.0, 1e-3, 1e-12, 1e-28])
def test_gamma_merge_of_equal_members_keeps_their_shape_down_to_vanishing_shapes(shape):
    """
    Members with one Gamma: the match ``log a - digamma(a) = log E[g] - E[log g]`` is
    solved by their own shape. A rate forgotten with a short ``model.tau_rate`` has a
    shape near 0, where ``c`` passes 1e16 and Minka's starting point, in its textbook
    form, cancelled to 0 (log 0 in the first Newton step, NaN weights after it).
    """
    from extended_tracker.filter.reduction import merge_gamma

    mix = evolve(mixture([0.6, 0.4], [14.0, 14.0], [extent(0.3, 0.2, 0.0)] * 2),
                 alpha=np.full(2, shape), beta=np.full(2, shape / 12.0))
    with np.errstate(all='raise'):
        out = merge_groups(mix, [np.arange(2)])
        a, b = merge_gamma(mix.w, mix.alpha, mix.beta)
    # Newton stops at a relative step of 1e-10 (1e-12 per group), and near 0 the equation
    # log a - digamma(a) = 1/a + O(log a) pins a to about that
    assert out.alpha[0] == pytest.approx(shape, rel=1e-8)
    assert a == pytest.approx(shape, rel=1e-8)
    assert out.alpha[0] / out.beta[0] == pytest.approx(12.0, rel=1e-8)
    assert a / b == pytest.approx(12.0, rel=1e-8)


def test_components_of_zero_weight_go_even_with_prune_weight_zero():
    """
    A CPHD whose cardinality rules out more objects gives some components a weight of
    exactly 0; with ``reduction.prune_weight`` 0 they were kept, and two of one label,
    both at 0, merged to 0/0 (NaN everywhere after).
    """
    X = [extent(0.3, 0.2, 0.0)] * 3
    mix = mixture([0.0, 0.0, 0.7], [14.0, 14.0, 14.0], X)
    mix = Mixture(mix.w, mix.alpha, mix.beta, mix.m, mix.P, mix.v, mix.V,
                  np.array([4, 4, 5], dtype=np.int64))
    with np.errstate(all='raise'):
        out, capped = reduce_mixture(mix, 0.0, 4.0, 100)
    assert out.label.tolist() == [5] and out.w.tolist() == [0.7] and capped == 0


def test_a_label_merges_what_lies_within_merge_distance_of_its_heaviest_and_keeps_the_rest():
    """Squared Mahalanobis distance in the heaviest component's position covariance
    (0.05 m std here, merge_distance 4): a member 0.075 m away (2.25) merges, one 0.125 m
    away (6.25) stays apart, whether the label's members are all near (one pass) or not
    (the greedy loop); other labels are never merged in."""
    near = pedestrians([(4, 0.6, 0.0, 0.0), (4, 0.3, 0.075, 0.0)])
    out, _ = reduce_mixture(near, 1e-6, 4.0, 100)
    assert len(out) == 1 and out.w[0] == pytest.approx(0.9)
    mixed = pedestrians([(4, 0.6, 0.0, 0.0), (4, 0.3, 0.075, 0.0), (4, 0.2, 0.0, 0.125),
                         (7, 0.5, 0.05, 0.0)])
    out, _ = reduce_mixture(mixed, 1e-6, 4.0, 100)
    assert sorted(zip(out.label.tolist(), np.round(out.w, 9).tolist())) == \
        [(4, 0.2), (4, 0.9), (7, 0.5)]


def test_a_member_under_a_hundredth_of_its_head_is_absorbed_a_heavier_one_moment_matched():
    """Within merge distance, a member under 1 % of its label's heaviest weight adds its
    weight and leaves the head as it was; a heavier one moves the merged mean to the
    weighted mean."""
    for w_member, mean in ((0.005, 0.0), (0.05, 0.05 * 0.05 / 1.05)):
        out, _ = reduce_mixture(pedestrians([(4, 1.0, 0.0, 0.0), (4, w_member, 0.05, 0.0)]),
                                1e-6, 4.0, 100)
        assert len(out) == 1 and out.w[0] == pytest.approx(1.0 + w_member, rel=1e-12)
        assert out.m[0, 0] == pytest.approx(mean, abs=1e-12)


def test_the_component_cap_keeps_the_heaviest():
    mix = pedestrians([(i + 1, w, float(i), 0.0) for i, w in
                       enumerate([0.2, 0.9, 0.4, 0.7, 0.1])])
    out, capped = reduce_mixture(mix, 1e-6, 4.0, 3)
    assert capped == 2 and sorted(out.label.tolist()) == [2, 3, 4]
    # in the order they had (ties of weight later break by position), not by weight
    assert out.label.tolist() == [2, 3, 4] and out.w.tolist() == [0.9, 0.4, 0.7]
