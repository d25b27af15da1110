"""
The cardinality pmf: Poisson tables, prediction (survival thinning plus Poisson
birth), and taking objects out of it or putting them back (``doc/model.md``, section 4).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import gammaln

from .logmath import lse1, lse_last, NEG_INF
from .tables import cached_tables


def poisson_log_pmf(mean: float, n_max: int) -> np.ndarray:
    """Log Poisson pmf at ``0..n_max`` (untruncated values)."""
    n = np.arange(n_max + 1)
    if mean <= 0:
        out = np.full(n_max + 1, -np.inf)
        out[0] = 0.0
        return out
    return n * np.log(mean) - mean - log_factorial(n_max)


def log_factorial(k: int) -> np.ndarray:
    """``log(i!)`` for ``i = 0..k`` (a cached table grown on demand)."""
    global _LF
    if len(_LF) <= k:
        _LF = gammaln(np.arange(max(k + 1, 2 * len(_LF))) + 1.0)
    return _LF[:k + 1]


_LF = gammaln(np.arange(256) + 1.0)


def predict_cardinality(log_card: np.ndarray, p_survival: float, birth_mean: float
                        ) -> np.ndarray:
    """
    Predicted cardinality: binomial thinning by survival, then Poisson birth, truncated.

    Notes
    -----
    ``p+(n) = sum_j p_B(n - j) sum_{l >= j} C(l, j) p_S^j (1 - p_S)^{l - j} p(l)``;
    the mass beyond ``N_max`` is dropped and the pmf renormalised.

    Computed on the pmf scaled by its largest entry: the binomial weights are
    probabilities, so the thinning keeps the total, at least that entry's 1, and a term
    that underflows is under 1e-308 of it. The thinning is ``(p_S / q_S)^j`` times
    ``sum_l C(l, j) q_S^l p(l)``, exact binomials and two vectors of powers in place of
    an ``exp`` of every weight (1681 at ``N_max`` 40, some 10 ns each on a CPU without a
    vectorised ``exp``), where neither power leaves the double range (``N_max`` times
    the larger log below 600, ``N_max`` up to ``THIN_PRODUCT_MAX``); else the weights'
    logs. The birth pmf is ``mean^k / k!`` by a running product (the result is
    renormalised, so its scale is free); where its largest entry up to ``N_max`` would
    pass 1e304 (a birth mean of 1e10), or no retained term is left, the log-domain form
    (:func:`predict_cardinality_log`) stands in. ``p_S`` changes with every scan
    period, so nothing here is cached per ``p_S``: a recording's stamps jitter, and
    tables cached per value were rebuilt every scan.
    """
    n_max = len(log_card) - 1
    p = np.exp(log_card - log_card.max())
    p_s = float(p_survival)
    n = _counts(n_max)
    if p_s <= 0.0:
        p = np.concatenate([[np.sum(p)], np.zeros(n_max)])
    elif p_s < 1.0:
        q_s = 1.0 - p_s
        if (n_max <= THIN_PRODUCT_MAX
                and n_max * max(abs(math.log(p_s / q_s)), -math.log(q_s)) < 600.0):
            p = (p_s / q_s) ** n * (binomial_table(n_max) @ (q_s ** n * p))
        else:
            log_comb, j, lj = _thinning_terms(n_max)
            p = np.exp(log_comb + (j * np.log(p_s) + lj * np.log1p(-p_s))) @ p
    mean = float(birth_mean)
    birth = np.empty(n_max + 1)
    birth[0] = 1.0
    if mean > 0.0:
        top = min(int(mean), n_max)                    # the largest mean^k / k! up to N_max
        if top * math.log(mean) - math.lgamma(top + 1) > 700.0:
            return predict_cardinality_log(log_card, p_s, mean)
        np.cumprod(mean / n[1:], out=birth[1:])
    else:
        birth[1:] = 0.0
    out = np.convolve(p, birth)[:n_max + 1]
    total = np.sum(out)
    if not (0.0 < total < np.inf):
        return predict_cardinality_log(log_card, p_s, mean)
    with np.errstate(divide='ignore'):
        return np.log(out / total)


# the product form of the binomial thinning up to this N_max (a table of (N_max + 1)^2
# exact binomials, cached)
THIN_PRODUCT_MAX = 400


@cached_tables(maxsize=16)
def _counts(n_max: int) -> np.ndarray:
    """``0, 1, .., N_max`` as floats."""
    return np.arange(n_max + 1, dtype=float)


@cached_tables(maxsize=16)
def binomial_table(n_max: int) -> np.ndarray:
    """``C(l, j)`` as a (j, l) table of floats (0 for ``j > l``), each exactly rounded."""
    return np.array([[float(math.comb(l_, j)) for l_ in range(n_max + 1)]
                     for j in range(n_max + 1)])


def predict_cardinality_log(log_card: np.ndarray, p_s: float, birth_mean: float
                             ) -> np.ndarray:
    """:func:`predict_cardinality` in the log domain, term by term."""
    n_max = len(log_card) - 1
    log_comb, j, lj = _thinning_terms(n_max)
    with np.errstate(divide='ignore', invalid='ignore'):
        log_ps = np.log(p_s)
        log_qs = np.log1p(-p_s) if p_s < 1 else NEG_INF
        term = np.where(j > 0, j * log_ps, 0.0) + np.where(lj > 0, lj * log_qs, 0.0)
    log_surv = lse_last(log_comb + term + log_card[None, :])
    n = np.arange(n_max + 1)
    diff = n[:, None] - n[None, :]
    log_birth = poisson_log_pmf(birth_mean, n_max)
    birth = np.where(diff >= 0, log_birth[np.clip(diff, 0, None)], NEG_INF)
    out = lse_last(log_surv[None, :] + birth)
    return out - lse1(out)


def thin_cardinality(log_card: np.ndarray, removed: float) -> np.ndarray:
    """
    The cardinality pmf after ``removed`` expected objects are taken away: whole objects
    one at a time, the last with the fractional remainder as its probability
    (``p'(n) = (1 - f) p(n) + f p(n + 1)``, ``p'(0)`` also gaining ``f p(1)``). Used when
    two tracks are found to be one object (``pairs.join_pairs``).

    Each step is a convex combination of neighbouring entries, so it runs on the pmf
    scaled by its largest entry: nothing that matters underflows.
    """
    return _shift_cardinality(log_card, removed, down=True)


def add_cardinality(log_card: np.ndarray, added: float) -> np.ndarray:
    """
    The cardinality pmf after ``added`` expected objects are put in, the converse of
    :func:`thin_cardinality`: whole objects one at a time, the last with the fractional
    remainder as its probability (``p'(n) = (1 - f) p(n) + f p(n - 1)``, ``p'(N_max)``
    also keeping ``f p(N_max)``: the pmf ends there). Below ``N_max`` the mean grows by
    ``added`` exactly.
    """
    return _shift_cardinality(log_card, added, down=False)


def _shift_cardinality(log_card: np.ndarray, count: float, down: bool) -> np.ndarray:
    """``count`` expected objects taken from (``down``) or put into a cardinality pmf,
    one whole object at a time and the fractional rest last; the end entry keeps what
    would leave the pmf."""
    p = np.exp(log_card - log_card.max())
    p /= p.sum()
    while count > 1e-12:
        f = min(count, 1.0)
        q = (1.0 - f) * p
        if down:
            q[:-1] += f * p[1:]
            q[0] += f * p[0]                       # nothing to take from none
        else:
            q[1:] += f * p[:-1]
            q[-1] += f * p[-1]                     # no room beyond N_max
        p = q
        count -= f
    with np.errstate(divide='ignore'):
        return np.log(p)


def resize_cardinality(log_card: np.ndarray, n_max: int) -> np.ndarray:
    """
    A cardinality pmf (log) carried over to ``0..n_max`` when ``N_max`` changes while the
    filter runs: padded with zeros, or truncated and renormalised (as the prediction drops
    the mass beyond ``N_max``); all at ``n_max`` if no mass was at or below it.
    """
    out = np.full(n_max + 1, -np.inf)
    k = min(len(log_card), n_max + 1)
    out[:k] = log_card[:k]
    total = lse1(out)
    if not np.isfinite(total):
        out[n_max] = 0.0
        return out
    return out - total


@cached_tables(maxsize=16)
def _thinning_terms(n_max: int):
    """``log C(l, j)`` as a (j, l) table (``-inf`` for ``j > l``), ``j`` as a column and
    ``max(l - j, 0)`` as a table: ``log C(l, j) + j log p_S + (l - j) log(1 - p_S)`` is the
    log of the binomial thinning weight."""
    n = np.arange(n_max + 1)
    lf = log_factorial(n_max)
    j, l_ = n[:, None], n[None, :]
    valid = j <= l_
    lj = np.where(valid, l_ - j, 0)
    log_comb = np.where(valid, lf[l_] - lf[j] - lf[lj], NEG_INF)
    return log_comb, j.astype(float), lj.astype(float)
