"""
Section 9 oracle: multi-object Bayes on a tiny discrete world, enumerated.

Object states are a handful of discrete values; detections are four labelled points with
arbitrary per-state densities. Every assignment of every detection to one of ``n``
labelled objects or to clutter is enumerated for every ``n``; the exact posterior
cardinality and the exact expected number of objects of each state that are missed or
that produced exactly the set ``W`` are compared with the partition update summed over all
partitions of the detections.
"""

from itertools import product

import numpy as np
import pytest
from scipy.special import gammaln

from extended_tracker.filter.cardinality import poisson_log_pmf
from extended_tracker.filter.cphd import cphd_update, phd_update

M = 4                      # detections
ALL = (1 << M) - 1


def set_partitions(items):
    """Every partition of the list ``items`` (Bell number many)."""
    if not items:
        yield []
        return
    first, rest = items[0], items[1:]
    for part in set_partitions(rest):
        for i in range(len(part)):
            yield part[:i] + [[first] + part[i]] + part[i + 1:]
        yield [[first]] + part


def make_world(seed, n_states=3, dead=None):
    rng = np.random.default_rng(seed)
    s = rng.dirichlet(np.ones(n_states))               # state distribution of one object
    p_d = rng.uniform(0.5, 0.95, n_states)
    gamma = rng.uniform(0.5, 3.0, n_states)            # Poisson rate of detections
    phi = rng.uniform(0.05, 2.0, (n_states, M))        # density of detection k under state l
    if dead is not None:
        phi[:, dead] = 0.0                             # no object can produce detection `dead`
    c = rng.uniform(0.1, 1.0, M)                       # clutter spatial density at each point
    # f(W | l): Poisson set density times p_D; f(empty | l) = q_D
    f = np.zeros((n_states, ALL + 1))
    for mask in range(ALL + 1):
        idx = [k for k in range(M) if mask >> k & 1]
        if idx:
            f[:, mask] = p_d * np.exp(-gamma) * gamma ** len(idx) * np.prod(phi[:, idx], axis=1)
        else:
            f[:, mask] = 1 - p_d + p_d * np.exp(-gamma)
    return s, f, c


def brute_force(card, s, f, c, clutter_pmf):
    """
    Exact posterior cardinality, missed and detected first moments by enumeration.

    Every assignment of the M detections to clutter or to one of n labelled objects is
    enumerated (numpy over the assignments); the sum over each object's state is done per
    object, which is exact because the prior objects are i.i.d. (checked against the full
    enumeration of states in brute_force_tuples).
    """
    n_states = len(s)
    h = s @ f                                          # object factor summed over its state
    n_max = len(card) - 1
    post_card = np.zeros(n_max + 1)
    missed = np.zeros(n_states)
    detected = np.zeros((n_states, ALL + 1))
    fact = np.exp(gammaln(np.arange(M + 1) + 1))
    kappa = np.zeros(ALL + 1)                          # clutter set density by mask
    for mask in range(ALL + 1):
        idx = [k for k in range(M) if mask >> k & 1]
        kappa[mask] = clutter_pmf[len(idx)] * fact[len(idx)] * np.prod(c[idx])
    for n in range(n_max + 1):
        if card[n] == 0:
            continue
        assign = np.array(list(product(range(n + 1), repeat=M))).reshape(-1, M)
        owner = np.arange(n + 1)
        bits = (assign[:, :, None] == owner[None, None, :]) * (1 << np.arange(M))[None, :, None]
        masks = bits.sum(axis=1)                       # (A, n + 1): mask of each owner
        objs = masks[:, 1:]
        base = card[n] * kappa[masks[:, 0]] * np.prod(h[objs], axis=1)
        post_card[n] += base.sum()
        for i in range(n):
            mk = objs[:, i]
            # where h = 0 the assignment has base 0: its share is 0, not 0/0
            share = base[:, None] * s[None, :] * f[:, mk].T / np.where(h[mk] > 0, h[mk],
                                                                      1.0)[:, None]
            np.add.at(detected.T, mk, share)
    missed = detected[:, 0].copy()
    detected[:, 0] = 0.0
    total = post_card.sum()
    return post_card / total, missed / total, detected / total


def brute_force_tuples(card, s, f, c, clutter_pmf):
    """The same with object states enumerated too (no factorisation), for small n."""
    n_states = len(s)
    n_max = len(card) - 1
    post_card = np.zeros(n_max + 1)
    missed = np.zeros(n_states)
    detected = np.zeros((n_states, ALL + 1))
    for n in range(n_max + 1):
        for states in product(range(n_states), repeat=n):
            prior = card[n] * np.prod(s[list(states)])
            for assign in product(range(n + 1), repeat=M):
                masks = [0] * (n + 1)
                for k, a in enumerate(assign):
                    masks[a] |= 1 << k
                clutter = [k for k in range(M) if masks[0] >> k & 1]
                kappa = clutter_pmf[len(clutter)] * np.exp(gammaln(len(clutter) + 1)) * \
                    np.prod(c[clutter])
                lik = kappa * np.prod([f[st, masks[i + 1]] for i, st in enumerate(states)])
                post_card[n] += prior * lik
                for i, st in enumerate(states):
                    if masks[i + 1] == 0:
                        missed[st] += prior * lik
                    else:
                        detected[st, masks[i + 1]] += prior * lik
    total = post_card.sum()
    return post_card / total, missed / total, detected / total


def filter_inputs(card, s, f, c):
    """Cells = all nonempty subsets; partitions = all set partitions; one component a state."""
    nbar = float(np.sum(np.arange(len(card)) * card))
    log_w = np.log(nbar * s)
    masks = list(range(1, ALL + 1))
    col = {mk: i for i, mk in enumerate(masks)}
    with np.errstate(divide='ignore'):                 # gated-out cells are -inf
        log_g = np.log(f[:, masks])
    log_qd = np.log(f[:, 0])
    size = np.array([bin(mk).count('1') for mk in masks])
    cell_log_c = np.array([np.sum(np.log(c[[k for k in range(M) if mk >> k & 1]]))
                           for mk in masks])
    parts = []
    for p in set_partitions(list(range(M))):
        parts.append(np.array([col[sum(1 << k for k in block)] for block in p]))
    assert len(parts) == 15                        # Bell(4)
    return log_w, log_qd, log_g, cell_log_c, size, parts, masks


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_factorised_oracle_matches_full_enumeration(seed):
    """The oracle's sum over states per object is exact (checked on a smaller world)."""
    s, f, c = make_world(seed, n_states=2)
    card = np.array([0.1, 0.3, 0.4, 0.2])
    pc = np.exp(poisson_log_pmf(0.7, M))
    a = brute_force(card, s, f, c, pc)
    b = brute_force_tuples(card, s, f, c, pc)
    for x, y in zip(a, b):
        np.testing.assert_allclose(x, y, rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize('seed', [0, 1, 2, 3])
@pytest.mark.parametrize('clutter', ['poisson', 'general'])
@pytest.mark.parametrize('dead', [None, 2])
@pytest.mark.parametrize('batched', [False, True])
def test_cphd_equals_brute_force(seed, clutter, dead, batched, monkeypatch):
    """
    Every partition of four detections; with ``dead``, one detection only clutter explains
    (an inactive singleton, and partitions whose non-singleton cells hold it are infeasible).
    ``batched`` splits the partitions into batches by singleton count, as large scans do.
    """
    if batched:
        import extended_tracker.filter.cphd as cphd_module

        monkeypatch.setattr(cphd_module, 'BATCH_MIN_PARTITIONS', 1)
        monkeypatch.setattr(cphd_module, 'BATCH_MIN_SINGLETONS', 1)
    s, f, c = make_world(seed, dead=dead)
    rng = np.random.default_rng(100 + seed)
    card = rng.dirichlet(np.ones(5))                   # arbitrary, N_max = 4
    if clutter == 'poisson':
        pc = np.exp(poisson_log_pmf(1.3, M))
        pc_full = pc
    else:
        pc_full = rng.dirichlet(np.ones(M + 1))        # not Poisson: any pmf on 0..M
        pc = pc_full
    ref_card, ref_missed, ref_det = brute_force(card, s, f, c, pc_full)
    log_w, log_qd, log_g, cell_log_c, size, parts, masks = filter_inputs(card, s, f, c)
    out = cphd_update(log_w, log_qd, log_g, cell_log_c, size, parts, np.log(card), np.log(pc))
    # Tolerance: both sides are sums of ~1e3 positive terms in double precision.
    np.testing.assert_allclose(np.exp(out.log_card), ref_card, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(np.exp(out.log_w_missed), ref_missed, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(np.exp(out.log_w_detected), ref_det[:, masks], rtol=1e-10,
                               atol=1e-14)
    # the first moment integrates to the posterior cardinality mean
    total = np.exp(out.log_w_missed).sum() + np.exp(out.log_w_detected).sum()
    assert total == pytest.approx(np.sum(np.arange(5) * ref_card), rel=1e-10)


def _check_against_brute_force(card, s, f, c, pc, log_pc=None):
    ref_card, ref_missed, ref_det = brute_force(card, s, f, c, pc)
    with np.errstate(divide='ignore'):                 # log 0 = -inf: the edge itself
        log_w, log_qd, log_g, cell_log_c, size, parts, masks = filter_inputs(card, s, f, c)
        out = cphd_update(log_w, log_qd, log_g, cell_log_c, size, parts, np.log(card),
                          np.log(pc) if log_pc is None else log_pc)
    np.testing.assert_allclose(np.exp(out.log_card), ref_card, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(np.exp(out.log_w_missed), ref_missed, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(np.exp(out.log_w_detected), ref_det[:, masks], rtol=1e-10,
                               atol=1e-14)


@pytest.mark.parametrize('seed', [0, 1])
def test_cphd_edges_equal_brute_force(seed):
    """
    The update's edge cases against enumeration: objects that are always detected (q_D =
    0 in every state, so q0 = 0 and 0 * log q0 must be 0); a prior with no objects at all
    (only clutter explains the scan); a clutter pmf shorter than the detections (more
    clutter than it allows is impossible: the filter pads it with zeros).
    """
    s, f, c = make_world(seed)
    rng = np.random.default_rng(200 + seed)
    card = rng.dirichlet(np.ones(5))
    pc = np.exp(poisson_log_pmf(1.3, M))
    always = f.copy()
    always[:, 0] = 0.0                                 # never missed
    _check_against_brute_force(card, s, always, c, pc)
    none = np.zeros(5)
    none[0] = 1.0                                      # surely no object
    _check_against_brute_force(none, s, f, c, pc)
    short = np.array([0.2, 0.5, 0.3])                  # at most two clutter detections
    _check_against_brute_force(card, s, f, c, np.concatenate([short, np.zeros(M - 2)]),
                               log_pc=np.log(short))


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_phd_equals_brute_force_with_poisson_prior(seed):
    s, f, c = make_world(seed)
    lam = 0.9
    mean = 0.5
    # The PHD update is exact for an untruncated Poisson prior; the oracle truncates at 13.
    # The posterior mass it drops is that of more than 13 - 4 undetected objects,
    # P(Poisson(0.5) > 9) ~ 2e-10, under the 1e-9 tolerance.
    card = np.exp(poisson_log_pmf(mean, 13))
    ref_card, ref_missed, ref_det = brute_force(card / card.sum(), s, f, c,
                                                np.exp(poisson_log_pmf(lam, M)))
    log_w, log_qd, log_g, _, size, parts, masks = filter_inputs(card / card.sum(), s, f, c)
    log_w = np.log(mean * s)
    cell_log_c = np.array([np.sum(np.log(c[[k for k in range(M) if mk >> k & 1]]))
                           for mk in masks])
    out = phd_update(log_w, log_qd, log_g, cell_log_c, size, parts, lam, 13)
    np.testing.assert_allclose(np.exp(out.log_w_missed), ref_missed, rtol=1e-9)
    np.testing.assert_allclose(np.exp(out.log_w_detected), ref_det[:, masks], rtol=1e-9,
                               atol=1e-14)
    # the CPHD with the same Poisson prior and Poisson clutter gives the same weights
    cp = cphd_update(log_w, log_qd, log_g, cell_log_c, size, parts,
                     np.log(card / card.sum()), poisson_log_pmf(lam, M))
    np.testing.assert_allclose(np.exp(cp.log_w_detected), np.exp(out.log_w_detected),
                               rtol=1e-9, atol=1e-14)
    np.testing.assert_allclose(np.exp(cp.log_card), ref_card, rtol=1e-9, atol=1e-14)


def _with_clutter_cell(card, s, f, c):
    """
    The filter's inputs for a world where detections 2 and 3 are clutter only, with them
    as one cell marked clutter: the partitions of {0, 1}, each with that cell.
    """
    log_w, log_qd, log_g, cell_log_c, size, _, masks = filter_inputs(card, s, f, c)
    col = {mk: i for i, mk in enumerate(masks)}
    both = col[0b1100]
    parts = [np.array([col[0b0011], both]), np.array([col[0b0001], col[0b0010], both])]
    clutter_cells = np.zeros(len(masks), dtype=bool)
    clutter_cells[both] = True
    return log_w, log_qd, log_g, cell_log_c, size, parts, masks, clutter_cells


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_a_cell_nothing_explains_is_clutter_return_by_return(seed):
    """
    Detections 2 and 3 only clutter explains, given to the update as one cell marked as
    clutter (as the tracker does with a cell too small to be born from that no object
    explains): the same posterior as the enumeration, where they are two clutter returns.
    Without the mark the cell makes both partitions impossible.
    """
    s, f, c = make_world(seed, dead=[2, 3])
    rng = np.random.default_rng(200 + seed)
    card = rng.dirichlet(np.ones(5))
    pc = rng.dirichlet(np.ones(M + 1))                 # not Poisson
    ref_card, ref_missed, ref_det = brute_force(card, s, f, c, pc)
    log_w, log_qd, log_g, cell_log_c, size, parts, masks, cc = _with_clutter_cell(
        card, s, f, c)
    assert not np.isfinite(log_g[:, cc]).any()
    # the pmf reaches 4 clutter returns: the cell's two and detections 0 and 1
    out = cphd_update(log_w, log_qd, log_g, cell_log_c, size, parts, np.log(card),
                      np.log(pc), cc)
    # Tolerance: as in test_cphd_equals_brute_force
    np.testing.assert_allclose(np.exp(out.log_card), ref_card, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(np.exp(out.log_w_missed), ref_missed, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(np.exp(out.log_w_detected), ref_det[:, masks], rtol=1e-10,
                               atol=1e-14)

    # the PHD with a Poisson prior (exact up to the oracle's truncation, see
    # test_phd_equals_brute_force_with_poisson_prior)
    lam, mean = 0.9, 0.5
    card = np.exp(poisson_log_pmf(mean, 13))
    ref_card, ref_missed, ref_det = brute_force(card / card.sum(), s, f, c,
                                                np.exp(poisson_log_pmf(lam, M)))
    out = phd_update(np.log(mean * s), log_qd, log_g, cell_log_c, size, parts, lam, 13, cc)
    np.testing.assert_allclose(np.exp(out.log_w_missed), ref_missed, rtol=1e-9)
    np.testing.assert_allclose(np.exp(out.log_w_detected), ref_det[:, masks], rtol=1e-9,
                               atol=1e-14)
    assert np.all(np.isfinite(out.log_partition_weight))


@pytest.mark.parametrize('mode', ['cphd', 'phd'])
def test_a_scan_no_partition_explains_leaves_the_prediction(mode):
    """
    The same partitions without the clutter mark (or none at all): no partition is
    possible, so the update says so and hands back the prediction, never NaN.
    """
    s, f, c = make_world(0, dead=[2, 3])
    card = np.random.default_rng(3).dirichlet(np.ones(5))
    log_w, log_qd, log_g, cell_log_c, size, parts, masks, _ = _with_clutter_cell(card, s, f, c)
    for partitions in (parts, []):
        if mode == 'cphd':
            out = cphd_update(log_w, log_qd, log_g, cell_log_c, size, partitions,
                              np.log(card), poisson_log_pmf(1.0, M))
            np.testing.assert_array_equal(out.log_card, np.log(card))
        else:
            out = phd_update(log_w, log_qd, log_g, cell_log_c, size, partitions, 1.0, 4)
            # the PHD's cardinality is Poisson with the predicted mean
            np.testing.assert_allclose(np.exp(out.log_card).sum(), 1.0, rtol=1e-12)
        assert not out.possible
        np.testing.assert_array_equal(out.log_w_missed, log_w)
        assert np.all(out.log_w_detected == -np.inf)
        assert len(out.log_partition_weight) == len(partitions)
    # and an update that is possible says so
    out = cphd_update(log_w, log_qd, log_g, cell_log_c, size, parts, np.log(card),
                      poisson_log_pmf(1.0, M), _with_clutter_cell(card, s, f, c)[-1])
    assert out.possible


def test_log_domain_survives_extreme_scales():
    """a_W spanning hundreds of orders of magnitude: no overflow, same normalised result."""
    s, f, c = make_world(5)
    card = np.array([0.2, 0.3, 0.3, 0.1, 0.1])
    pc = np.exp(poisson_log_pmf(1.0, M))
    log_w, log_qd, log_g, cell_log_c, size, parts, masks = filter_inputs(card, s, f, c)
    base = cphd_update(log_w, log_qd, log_g, cell_log_c, size, parts, np.log(card), np.log(pc))
    # scaling the clutter density by e^{-300} per point and the likelihoods the same way
    # leaves the posterior unchanged
    shift = 300.0 * size
    out = cphd_update(log_w, log_qd, log_g - shift[None, :], cell_log_c - shift, size, parts,
                      np.log(card), np.log(pc))
    np.testing.assert_allclose(out.log_card, base.log_card, atol=1e-9)
    np.testing.assert_allclose(out.log_w_detected, base.log_w_detected, atol=1e-9)
    assert np.all(np.isfinite(out.log_w_missed))


def _padded(rows, k):
    """Rows of values as log-rows of width ``k``, padded with -inf."""
    log_a = np.full((len(rows), k), -np.inf)
    for i, a in enumerate(rows):
        log_a[i, :len(a)] = np.log(a)
    return log_a


def _enumerated(a, log_b):
    """By enumeration: ``e_r(a)`` for r = 0..len(a), and for each j
    ``sum_r e_r(a without a_j) b_r``."""
    from itertools import combinations

    def esf(v):
        return [sum(np.prod(c) for c in combinations(v, r)) for r in range(len(v) + 1)]

    loo = []
    for j in range(len(a)):
        e = esf(np.delete(a, j))
        loo.append(sum(np.exp(log_b[r]) * e[r] for r in range(len(e))))
    return esf(a), loo


def test_leave_one_out_sums_against_direct_products():
    """Batched prefix ESFs and leave-one-out sums, rows padded with -inf, by enumeration."""
    from extended_tracker.filter.esf import leave_one_out_sums, log_esf_prefixes

    rng = np.random.default_rng(3)
    k = 6
    rows = [rng.uniform(0.05, 5.0, k), rng.uniform(0.05, 5.0, 3), np.exp([-400.0, 300.0])]
    log_a = _padded(rows, k)
    log_b = np.log(rng.uniform(0.1, 3.0, (len(rows), k)))
    pre = log_esf_prefixes(log_a)
    out = leave_one_out_sums(pre, log_a, log_b)
    for i, a in enumerate(rows):
        e_full, loo = _enumerated(a, log_b[i])
        # rtol: sums of at most 20 positive products in double precision
        np.testing.assert_allclose(np.exp(pre[len(a), i, :len(a) + 1]), e_full, rtol=1e-12)
        assert np.all(pre[len(a), i, len(a) + 1:] == -np.inf)
        for j, ref in enumerate(loo):
            if i == 2:                                 # 1e-174 and 1e130: compare logs
                assert out[i, j] == pytest.approx(np.log(ref), rel=1e-12)
            else:
                assert np.exp(out[i, j]) == pytest.approx(ref, rel=1e-12)
        # leaving out a padding element (a zero) leaves the whole row
        if len(a) < k:
            full = np.log(sum(np.exp(log_b[i, r]) * e_full[r] for r in range(len(a) + 1)))
            np.testing.assert_allclose(out[i, len(a):], full, rtol=1e-12)


def _log_domain_terms(log_a, log_b):
    from extended_tracker.filter.esf import leave_one_out_sums, log_esf_prefixes

    pre = log_esf_prefixes(log_a)
    return pre[log_a.shape[1]], leave_one_out_sums(pre, log_a, log_b)


def test_scaled_esf_terms_against_enumeration(monkeypatch):
    """The linear-domain path: e_r and leave-one-out sums of padded rows by enumeration,
    with values spread over 80 orders of magnitude (inside the path's floor)."""
    from extended_tracker.filter import esf

    rng = np.random.default_rng(8)
    k = 6
    rows = [rng.uniform(0.05, 5.0, k), rng.uniform(0.05, 5.0, 3),
            np.exp([-90.0, 95.0, 3.0]), np.zeros(0)]
    log_a = _padded(rows, k)
    log_b = np.log(rng.uniform(0.1, 3.0, (len(rows), k))) + 40.0 * np.arange(k)
    spy = []
    real = esf.log_esf_prefixes
    monkeypatch.setattr(esf, 'log_esf_prefixes', lambda x: spy.append(1) or real(x))
    log_e, loo = esf.esf_terms(log_a, log_b, min_work=0)
    assert not spy                                      # the scaled path was taken
    for i, a in enumerate(rows):
        e_full, loo_ref = _enumerated(a, log_b[i])
        np.testing.assert_allclose(log_e[i, :len(a) + 1], np.log(e_full), rtol=1e-13,
                                   atol=1e-13)
        assert np.all(log_e[i, len(a) + 1:] == -np.inf)
        for j, ref in enumerate(loo_ref):
            assert loo[i, j] == pytest.approx(np.log(ref), rel=1e-13)


def test_scaled_esf_terms_match_the_log_domain_recursions():
    """Random batches like the CPHD update's (active singletons of each partition, -inf
    padded, coefficients -inf past each row's count): both paths agree to rounding."""
    from extended_tracker.filter.esf import esf_terms

    rng = np.random.default_rng(9)
    for trial in range(20):
        p, k = rng.integers(1, 8), rng.integers(1, 40)
        count = rng.integers(0, k + 1, p)
        log_a = rng.normal(0.0, 6.0, (p, k)) + rng.normal(0.0, 20.0, (p, 1))
        log_b = rng.normal(0.0, 30.0, (p, k)) + 5.0 * np.arange(k)
        for i, c in enumerate(count):
            log_a[i, c:] = -np.inf
            log_b[i, c:] = -np.inf
        log_e, loo = esf_terms(log_a, log_b, min_work=0)
        ref_e, ref_loo = _log_domain_terms(log_a, log_b)
        np.testing.assert_allclose(log_e, ref_e, rtol=1e-12, atol=1e-9)
        for i, c in enumerate(count):                   # the sums the update reads
            np.testing.assert_allclose(loo[i, :c], ref_loo[i, :c], rtol=1e-12, atol=1e-9)
        e_only, none = esf_terms(log_a, None, min_work=0)
        assert none is None and np.array_equal(e_only, log_e)


@pytest.mark.parametrize('k', [0, 1, 2])
def test_esf_terms_of_rows_of_up_to_two_are_the_recursions_to_the_bit(k):
    """Rows of at most two values (most partitions' active singletons) take closed forms:
    the same values, bit for bit, as the log-domain recursions, -inf padding included, with
    and without coefficients."""
    from extended_tracker.filter.esf import esf_terms, leave_one_out_sums, log_esf_prefixes

    rng = np.random.default_rng(k)
    for trial in range(300):
        p = int(rng.integers(1, 6))
        log_a = rng.normal(0.0, 50.0, (p, k))
        log_b = rng.normal(0.0, 50.0, (p, k))
        log_a[rng.random((p, k)) < 0.3] = -np.inf
        log_b[rng.random((p, k)) < 0.2] = -np.inf
        pre = log_esf_prefixes(log_a)
        log_e, loo = esf_terms(log_a, log_b)
        assert np.array_equal(log_e, pre[k])
        assert np.array_equal(loo, leave_one_out_sums(pre, log_a, log_b))
        e_only, none = esf_terms(log_a, None)
        assert none is None and np.array_equal(e_only, pre[k])


def test_esf_terms_keep_the_log_domain_for_extreme_spreads():
    """A row whose values span hundreds of orders of magnitude (their scaled product
    below the floor) sends the batch to the log-domain recursions, values unchanged; so
    does a batch smaller than ``min_work``."""
    from extended_tracker.filter import esf

    log_a = np.array([[0.0, -300.0, -400.0], [1.0, 2.0, -np.inf]])
    log_b = np.array([[0.0, 1.0, 2.0], [0.5, 0.2, -np.inf]])
    assert (log_a[0] - log_a[0].max()).sum() < esf.LINEAR_FLOOR
    log_e, loo = esf.esf_terms(log_a, log_b, min_work=0)
    ref_e, ref_loo = _log_domain_terms(log_a, log_b)
    assert np.array_equal(log_e, ref_e) and np.array_equal(loo, ref_loo)
    small = esf.esf_terms(log_a[1:], log_b[1:])          # 1 x 3^2 elements
    ref_small = _log_domain_terms(log_a[1:], log_b[1:])
    assert np.array_equal(small[0], ref_small[0]) and np.array_equal(small[1], ref_small[1])


def test_the_poisson_pmf_of_mean_zero_is_all_at_none():
    """Mean 0: the pmf is 1 at n = 0 and 0 elsewhere (log: 0 and -inf), as scipy says of
    every positive mean in the limit."""
    from scipy.stats import poisson

    np.testing.assert_array_equal(poisson_log_pmf(0.0, 3), [0.0, -np.inf, -np.inf, -np.inf])
    np.testing.assert_allclose(poisson_log_pmf(2.5, 6), poisson.logpmf(np.arange(7), 2.5),
                               rtol=1e-14)


def test_the_log_factorial_table_grows_to_any_length():
    """The cached table of log n! grows on demand to hold the entry asked for, however
    far past twice its length that is; its values are scipy's gammaln(n + 1)."""
    from extended_tracker.filter import cardinality

    for k in (10, 11, 100, 300, 5000):
        got = cardinality.log_factorial(k)
        assert len(got) == k + 1
        np.testing.assert_allclose(got, gammaln(np.arange(k + 1) + 1.0), rtol=1e-15)


def test_esf_terms_of_a_thousand_equal_values_are_log_binomials():
    """1100 values of 1: e_r is C(1100, r), up to 1e329, past the largest double, so the
    scaled linear path must not be taken for such a row (LINEAR_MAX_R); the log-domain
    path gives log C(1100, r) to rounding. The oracle: gammaln."""
    from extended_tracker.filter.esf import esf_terms

    k = 1100
    log_e, _ = esf_terms(np.zeros((1, k)), None, min_work=0)
    r = np.arange(k + 1)
    want = gammaln(k + 1.0) - gammaln(r + 1.0) - gammaln(k - r + 1.0)
    np.testing.assert_allclose(log_e[0], want, rtol=1e-11, atol=1e-9)


def test_esf_terms_give_an_empty_sum_for_a_row_without_coefficients():
    """A row whose coefficients are all -inf (a partition with no active singleton in a
    batch with some) has leave-one-out sums of nothing: -inf, not NaN, on the scaled
    path as on the log-domain one."""
    from extended_tracker.filter.esf import esf_terms

    rng = np.random.default_rng(3)
    p, k = 10, 24
    log_a = rng.normal(0.0, 1.0, (p, k))
    log_b = rng.normal(0.0, 1.0, (p, k))
    log_b[4] = -np.inf
    for min_work in (0, 10 ** 9):                       # scaled, then the log domain
        with np.errstate(all='raise'):
            _, loo = esf_terms(log_a, log_b, min_work=min_work)
        assert np.all(loo[4] == -np.inf) and np.all(np.isfinite(np.delete(loo, 4, axis=0)))


def test_with_no_predicted_objects_the_cardinality_is_the_prediction():
    """No component to detect: whatever the predicted pmf holds stays unseen (every
    object missed for sure), the returns are clutter, and the posterior cardinality is
    the predicted one. Oracle: Bayes with a likelihood that does not depend on n."""
    rng = np.random.default_rng(5)
    log_card = np.log(rng.dirichlet(np.ones(6)))
    clutter = poisson_log_pmf(2.0, 10)
    out = cphd_update(np.zeros(0), np.zeros(0), np.zeros((0, 3)), np.full(3, -np.log(50.0)),
                      np.ones(3, dtype=np.int64), [np.arange(3)], log_card, clutter)
    np.testing.assert_allclose(out.log_card, log_card, rtol=1e-12, atol=1e-12)
    assert out.possible and out.log_w_detected.shape == (0, 3)
