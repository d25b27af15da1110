"""The package's log-sum-exp helpers against scipy.special.logsumexp (the oracle)."""

from hypothesis import given, strategies as st
import numpy as np
from scipy.special import logsumexp as scipy_lse

from extended_tracker.filter.logmath import logsumexp, lse1, lse_last, LSE_REDUCE_MAX

values = st.lists(st.one_of(st.floats(-800, 800), st.just(-np.inf)), min_size=1, max_size=12)


@given(st.lists(values, min_size=1, max_size=5).filter(
    lambda rows: len({len(r) for r in rows}) == 1))
def test_equal_to_scipy(rows):
    a = np.array(rows, dtype=float)
    with np.errstate(divide='ignore'):
        ref_rows = scipy_lse(a, axis=1)
        ref_cols = scipy_lse(a, axis=0)
        ref_all = scipy_lse(a)
    # rounding: scipy sums exp(a - max); lse_last (arrays this small) folds logaddexp,
    # within some units in the last place per element of a row
    np.testing.assert_allclose(lse_last(a), ref_rows, rtol=1e-12, atol=1e-12)
    # the last axis of a 3-d stack, as the batched CPHD update uses it
    stack = np.stack([a, a[::-1]])
    with np.errstate(divide='ignore'):
        ref_stack = scipy_lse(stack, axis=-1)
    np.testing.assert_allclose(lse_last(stack), ref_stack, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(logsumexp(a, axis=1), ref_rows, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(logsumexp(a, axis=0), ref_cols, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(logsumexp(a), ref_all, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(lse1(a[0]), scipy_lse(a[0]), rtol=1e-12, atol=1e-12)


def test_lse_last_above_the_reduction_size_takes_the_shifted_sum():
    """Past LSE_REDUCE_MAX elements lse_last sums exp(a - max): the same values as scipy
    and as its logaddexp reduction on the same rows, all -inf rows included."""
    rng = np.random.default_rng(7)
    a = rng.normal(0.0, 200.0, size=(LSE_REDUCE_MAX // 40 + 1, 41))
    a[3] = -np.inf
    a[5, ::2] = -np.inf
    assert a.size > LSE_REDUCE_MAX
    with np.errstate(divide='ignore'):
        ref = scipy_lse(a, axis=-1)
    big = lse_last(a)
    # the reduction on the same rows a few at a time (each call under the size)
    rows = np.concatenate([lse_last(a[i:i + 10]) for i in range(0, len(a), 10)])
    assert big[3] == rows[3] == -np.inf
    # tolerance: both are double-precision sums of at most 41 positive terms
    np.testing.assert_allclose(big, ref, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(rows, ref, rtol=1e-12, atol=1e-12)


def test_empty_and_all_minus_infinity():
    assert lse1(np.zeros(0)) == -np.inf
    assert logsumexp(np.zeros(0)) == -np.inf
    assert lse1(np.full(3, -np.inf)) == -np.inf
    assert np.all(lse_last(np.full((2, 3), -np.inf)) == -np.inf)
    assert np.all(lse_last(np.full((2, 2, 3), -np.inf)) == -np.inf)
    assert lse_last(np.zeros((3, 0))).tolist() == [-np.inf] * 3
