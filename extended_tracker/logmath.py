"""Small log-domain helpers (numpy only; scipy's logsumexp carries array-API overhead)."""

from __future__ import annotations

import numpy as np


def logsumexp(a, axis=None):
    """
    ``log(sum(exp(a)))`` along ``axis``, stable, ``-inf`` for empty or all ``-inf`` input.

    Same values as ``scipy.special.logsumexp`` (checked in the tests) without its per-call
    dispatch cost, which dominates on the small arrays of the partition loop.
    """
    a = np.asarray(a, dtype=float)
    if a.size == 0:
        if axis is None:
            return -np.inf
        shape = list(a.shape)
        del shape[axis]
        return np.full(shape, -np.inf)
    amax = np.max(a, axis=axis, keepdims=True)
    amax = np.where(np.isfinite(amax), amax, 0.0)
    with np.errstate(divide='ignore'):
        out = np.log(np.sum(np.exp(a - amax), axis=axis, keepdims=True)) + amax
    if axis is None:
        return float(out.reshape(()))
    return np.squeeze(out, axis=axis)


def lse1(a: np.ndarray) -> float:
    """``logsumexp`` of a 1-D float array, for the hot loops (no argument checking)."""
    if not a.size:
        return -np.inf
    m = np.maximum.reduce(a)
    if m == -np.inf:
        return -np.inf
    return float(m + np.log(np.add.reduce(np.exp(a - m))))


def lse_last(a: np.ndarray) -> np.ndarray:
    """``logsumexp`` over the last axis of an N-d float array (slices may be all ``-inf``)."""
    # an all -inf slice is shifted by the lowest finite double instead of its max (exp
    # gives 0 either way) and its log(0) is never evaluated: no errstate (2 us) per call
    safe = np.maximum(np.maximum.reduce(a, axis=-1), _LOWEST)
    s = np.add.reduce(np.exp(a - safe[..., None]), axis=-1)
    return safe + np.log(s, out=neg_inf(s.shape), where=s > 0)


_LOWEST = np.finfo(float).min


def neg_inf(shape) -> np.ndarray:
    """A new float array of ``-inf``: ``np.full(shape, -np.inf)`` without its Python
    wrapper (a dozen such tables a step)."""
    out = np.empty(shape)
    out.fill(-np.inf)
    return out
