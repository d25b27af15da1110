"""
Elementary symmetric functions in the log domain, and their leave-one-out sums: the
sums over the singleton cells of a partition that the CPHD update needs
(``doc/model.md``, section 4).
"""

from __future__ import annotations

import numpy as np

from .logmath import lse_last, NEG_INF


def log_esf_prefixes(log_a: np.ndarray) -> np.ndarray:
    """
    Log elementary symmetric functions of every prefix of every row.

    Parameters
    ----------
    log_a : (p, k) array
        Rows of log-values; ``-inf`` entries (padding) change nothing.

    Returns
    -------
    (k + 1, p, k + 1) array
        ``out[t, i, r] = log e_r(a_i0 .. a_i(t-1))``.

    Notes
    -----
    Recursion ``e_r <- e_r + a_t e_{r-1}`` over ``t``, each step a ``logaddexp`` on all rows
    at once; stable for values spanning hundreds of orders of magnitude.

    """
    p, k = log_a.shape
    pre = np.full((k + 1, p, k + 1), -np.inf)
    pre[:, :, 0] = 0.0
    for t in range(k):
        pre[t + 1, :, 1:] = np.logaddexp(pre[t, :, 1:], pre[t, :, :-1] + log_a[:, t:t + 1])
    return pre


def leave_one_out_sums(pre: np.ndarray, log_a: np.ndarray, log_b: np.ndarray) -> np.ndarray:
    """
    ``log sum_r e_r(a_i without a_ij) b_ir`` for every row ``i`` and element ``j``.

    Parameters
    ----------
    pre : (k + 1, p, k + 1) array
        :func:`log_esf_prefixes` of ``log_a``.
    log_a : (p, k) array
    log_b : (p, k) array
        Log-coefficients ``b_ir``, ``r = 0..k-1``.

    Returns
    -------
    (p, k) array

    Notes
    -----
    ``e(a without a_j)`` is the product of the polynomials of the prefix before ``j`` and
    the suffix after it, so the sum is ``sum_i pre_j[i] G_j[i]`` with
    ``G_j[i] = sum_s e_s(suffix after j) b_{i+s}``. Absorbing ``a_j`` into the suffix gives
    ``G_{j-1}[i] = G_j[i] + a_j G_j[i+1]``: O(k) per element, O(k^2) in all, every term
    positive (no division, so no cancellation), against O(k^3) for masking each element
    in turn.

    """
    p, k = log_a.shape
    g = np.full((k + 1, p, k + 1), -np.inf)               # g[j] = G_j, padded by one column
    g[k, :, :k] = log_b
    for j in range(k - 1, 0, -1):
        g[j, :, :k] = np.logaddexp(g[j + 1, :, :k], log_a[:, j:j + 1] + g[j + 1, :, 1:])
    # element j pairs the prefix before it with the suffix after it
    return lse_last(pre[:k, :, :k] + g[1:, :, :k]).T


# The scaled (linear-domain) symmetric functions are used when the product of a row's
# scaled values is at least e^LINEAR_FLOOR: then every e_r and every leave-one-out sum is
# at least that, and the terms that underflow (below 1e-308, at most C(R, r) of them) are
# some 1e-40 of it. LINEAR_MAX_R keeps C(R, r) 2^R far below the largest double.
LINEAR_FLOOR = -575.0


LINEAR_MAX_R = 400


# below this many elements (p k^2) the log-domain recursions cost less than the scaling's
# own set-up (measured: 1.5-2x faster from p = 10, k = 24; slower at k <= 16)
LINEAR_MIN_WORK = 5000


def esf_terms(log_a: np.ndarray, log_b: np.ndarray | None, min_work: int = LINEAR_MIN_WORK):
    """
    ``log e_r`` of every row and, with ``log_b``, the leave-one-out sums of
    :func:`leave_one_out_sums`, in the linear domain where that is exact to rounding.

    Parameters
    ----------
    log_a : (p, k) array
        Rows of log-values, ``-inf`` padded.
    log_b : (p, k) array or None
        Log-coefficients ``b_ir``; None when only the ``e_r`` are needed.
    min_work : int
        Batches of fewer than this many elements ``p k^2`` take the log-domain path.

    Returns
    -------
    log_e : (p, k + 1) array
        ``log e_r(a_i)``.
    loo : (p, k) array or None
        ``log sum_r e_r(a_i without a_ij) b_ir``.

    Notes
    -----
    The log-domain recursions (:func:`log_esf_prefixes`, :func:`leave_one_out_sums`) cost
    an ``exp`` and a ``log1p`` per element and step, O(p k^2) of them, and a CPU without a
    vectorised ``exp`` pays some 10 ns for each. Scaled by each row's largest value
    (``b = a / max``, all in (0, 1]) the same recursions are multiply-adds with
    positive terms (no cancellation), and only the O(p k) results take a ``log``. Each
    ``e_r`` is at least the product of all the row's scaled values, so when that product
    is above ``e^LINEAR_FLOOR`` nothing that matters underflows; a batch with a row
    below it (values spread over hundreds of orders of magnitude) takes the log-domain
    path, and so does a small batch, where the scaling's set-up costs more than it saves.
    """
    p, k = log_a.shape
    scaled = p * k * k >= min_work and k <= LINEAR_MAX_R
    if scaled:
        # each row scaled by its largest value (0 for a row of padding only)
        mx = log_a.max(axis=1, initial=NEG_INF)
        mx = np.where(np.isfinite(mx), mx, 0.0)
        shifted = log_a - mx[:, None]                 # padding stays -inf
        log_prod = np.where(np.isfinite(shifted), shifted, 0.0).sum(axis=1)
        scaled = log_prod.min(initial=0.0) >= LINEAR_FLOOR
    if not scaled:
        if k <= 2:
            return _esf_two(log_a, log_b)
        pre = log_esf_prefixes(log_a)
        return pre[k], None if log_b is None else leave_one_out_sums(pre, log_a, log_b)
    b = np.exp(shifted)                               # padding -> 0
    E = np.zeros((k + 1, p, k + 1))
    E[:, :, 0] = 1.0
    for t in range(k):
        np.add(E[t, :, 1:], b[:, t:t + 1] * E[t, :, :-1], out=E[t + 1, :, 1:])
    r = np.arange(k + 1)
    with np.errstate(divide='ignore'):
        log_e = np.log(E[k]) + r * mx[:, None]
        if log_b is None:
            return log_e, None
        # sum_r e_r(a without j) b_r = sum_r e_r(b without j) e^{r mx} b_r: fold e^{r mx}
        # into the coefficients and scale them by their row's largest
        log_c = log_b + r[None, :k] * mx[:, None]
        cm = log_c.max(axis=1, initial=NEG_INF)
        cm = np.where(np.isfinite(cm), cm, 0.0)
        G = np.zeros((k + 1, p, k + 1))
        G[k, :, :k] = np.exp(log_c - cm[:, None])
        for j in range(k - 1, 0, -1):
            np.add(G[j + 1, :, :k], b[:, j:j + 1] * G[j + 1, :, 1:], out=G[j, :, :k])
        loo = np.log(np.sum(E[:k, :, :k] * G[1:, :, :k], axis=2).T) + cm[:, None]
    return log_e, loo


def _esf_two(log_a: np.ndarray, log_b: np.ndarray | None):
    """
    :func:`esf_terms` of rows of at most two values, in closed form: ``e_1 = a_0 + a_1``,
    ``e_2 = a_0 a_1`` and the leave-one-out sums ``b_0 + a_other b_1`` (logs). Step by
    step the recursions of :func:`log_esf_prefixes` and :func:`leave_one_out_sums` reduce
    to the same operations on the same values (a ``logaddexp`` with ``-inf`` returns the
    other term exactly), so the results are theirs to the bit; most partitions of a scan
    hold at most two active singletons, where the recursions' set-up is most of the cost.
    """
    p, k = log_a.shape
    log_e = np.zeros((p, k + 1))
    if k == 1:
        log_e[:, 1] = log_a[:, 0]
        loo = None if log_b is None else log_b.copy()
    elif k == 2:
        a0, a1 = log_a[:, 0], log_a[:, 1]
        np.logaddexp(a0, a1, out=log_e[:, 1])
        np.add(a0, a1, out=log_e[:, 2])
        loo = None if log_b is None else np.logaddexp(log_b[:, :1],
                                                      log_a[:, ::-1] + log_b[:, 1:])
    else:
        loo = None if log_b is None else np.zeros((p, 0))
    return log_e, loo
