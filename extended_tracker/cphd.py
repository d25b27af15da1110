"""
The multiple extended object update over partitions (ET-CPHD and its ET-PHD special case).

Everything here works on log-weights and log-likelihoods; no GGIW detail enters, so the
same code is tested exactly against brute-force multi-object Bayes on a discrete world.

Notes
-----
Section 4 of ``docs/ggiw-cphd.md``; Lundquist, Granström & Orguner, IEEE JSTSP 7(3), 2013
(ET-CPHD) and Granström, Lundquist & Orguner, IEEE TAES 48(4), 2012 (ET-PHD). For a
partition ``P`` with ``k`` cells, ``k2`` of them non-singleton::

    Lambda_P(n) = A_P sum_{j=k2}^{min(k,n)} (k-j)! p_c(k-j) n!/(n-j)! q0^{n-j} e_{j-k2}(a_S)

with ``A_P`` the product of ``a_W`` over non-singleton cells and ``e_r`` the elementary
symmetric function over the singleton cells.

"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import gammaln, logsumexp

NEG_INF = -np.inf


@dataclass(frozen=True)
class UpdateWeights:
    """
    Posterior weights of the multi-object update.

    Attributes
    ----------
    log_w_missed : (n,) array
        Log-weight of each predicted component left un-updated (missed detection).
    log_w_detected : (n, c) array
        Log-weight of component ``i`` updated with cell ``c``, summed over all partitions
        holding ``c`` (the updated GGIW is the same in each). ``-inf`` where gated out.
    log_card : (N_max + 1,) array
        Posterior cardinality pmf (log).
    log_partition_weight : (p,) array
        Normalised log-weight of each partition (its share of the likelihood).

    """

    log_w_missed: np.ndarray
    log_w_detected: np.ndarray
    log_card: np.ndarray
    log_partition_weight: np.ndarray


def log_esf(log_a: np.ndarray) -> np.ndarray:
    """
    Log elementary symmetric functions ``log e_r(a)``, ``r = 0..len(a)``.

    Notes
    -----
    Recursion ``e_r <- e_r + a_t e_{r-1}`` over ``t``, each step a ``logaddexp``; stable for
    values spanning hundreds of orders of magnitude.

    """
    k = len(log_a)
    e = np.full(k + 1, NEG_INF)
    e[0] = 0.0
    for t in range(k):
        e[1:t + 2] = np.logaddexp(e[1:t + 2], e[0:t + 1] + log_a[t])
    return e


def log_esf_leave_one_out(log_a: np.ndarray) -> np.ndarray:
    """
    ``log e_r(a without a_j)`` for every ``j``: array of shape (k, k), ``r = 0..k-1``.

    Notes
    -----
    The recursion of :func:`log_esf` run for all ``j`` at once, element ``j`` masked in
    row ``j``; no division, so no cancellation.

    """
    k = len(log_a)
    e = np.full((k, k + 1), NEG_INF)
    e[:, 0] = 0.0
    masked = np.broadcast_to(log_a, (k, k)).copy()
    np.fill_diagonal(masked, NEG_INF)
    for t in range(k):
        e[:, 1:t + 2] = np.logaddexp(e[:, 1:t + 2], e[:, 0:t + 1] + masked[:, t:t + 1])
    return e[:, :k]


def poisson_log_pmf(mean: float, n_max: int) -> np.ndarray:
    """Log Poisson pmf at ``0..n_max`` (untruncated values)."""
    n = np.arange(n_max + 1)
    if mean <= 0:
        out = np.full(n_max + 1, NEG_INF)
        out[0] = 0.0
        return out
    return n * np.log(mean) - mean - gammaln(n + 1)


def _log_lambda_table(log_q0: float, n_max: int, j_max: int) -> np.ndarray:
    """``T[n, j] = log(n!/(n-j)!) + (n-j) log q0`` for ``j <= n``, else ``-inf``."""
    n = np.arange(n_max + 1)[:, None]
    j = np.arange(j_max + 1)[None, :]
    lf = gammaln(np.arange(n_max + 2) + 1)
    valid = j <= n
    nj = np.where(valid, n - j, 0)
    with np.errstate(invalid='ignore'):
        # 0 * log q0 must be 0 even when q0 = 0 (log q0 = -inf)
        q_term = np.where(nj > 0, nj * log_q0, 0.0)
    T = lf[n] - lf[nj] + q_term
    return np.where(valid, T, NEG_INF)


def _log_lambda(T, log_pc_fact, log_A, k1, k2, log_e):
    """
    ``log Lambda(n)`` for ``n = 0..N_max`` (see module notes).

    ``log_e`` holds ``log e_r`` of the singletons with nonzero ``a``, ``r = 0..len-1``;
    singletons with ``a = 0`` only count as possible clutter (``k1`` includes them).
    """
    r = np.arange(len(log_e))
    j = k2 + r
    ok = j < T.shape[1]
    r, j = r[ok], j[ok]
    terms = T[:, j] + (log_pc_fact[k1 - r] + log_e[r])[None, :]
    return log_A + logsumexp(terms, axis=1)


def cphd_update(log_w, log_qd, log_g, cell_log_c, cell_size, partitions, log_card,
                log_clutter_pmf) -> UpdateWeights:
    """
    ET-CPHD update in the log domain.

    Parameters
    ----------
    log_w : (n,) array
        Predicted component log-weights.
    log_qd : (n,) array
        Log probability of no detection of each component.
    log_g : (n, c) array
        ``log(p_D,i l_{i,W})`` for component ``i`` and cell ``W``; ``-inf`` where gated out.
    cell_log_c : (c,) array
        ``log c^W = sum_{z in W} log c(z)`` (clutter spatial density).
    cell_size : (c,) int array
        ``|W|``.
    partitions : list of int arrays
        Each a partition of the detections as indices into the cells.
    log_card : (N_max + 1,) array
        Predicted cardinality pmf (log).
    log_clutter_pmf : (M,) array
        Clutter cardinality pmf (log), ``M`` larger than the most cells in a partition.

    Returns
    -------
    UpdateWeights

    """
    log_w = np.asarray(log_w, dtype=float)
    n_comp, n_cells = log_g.shape
    n_max = len(log_card) - 1
    log_nbar = logsumexp(log_w) if n_comp else NEG_INF
    if not np.isfinite(log_nbar):
        # no predicted objects: only clutter explains the scan
        log_nbar = 0.0
        log_q0 = 0.0
    else:
        log_q0 = logsumexp(log_w + log_qd) - log_nbar
    # log a_W = log(psi_W / c^W), psi_W = sum_i w_i g_iW / Nbar
    if n_comp:
        log_psi = logsumexp(log_w[:, None] + log_g, axis=0) - log_nbar
    else:
        log_psi = np.full(n_cells, NEG_INF)
    log_a = log_psi - cell_log_c
    k_most = max((len(p) for p in partitions), default=0)
    T = _log_lambda_table(log_q0, n_max, k_most)
    lf = gammaln(np.arange(k_most + 2) + 1)
    need = k_most + 1
    if len(log_clutter_pmf) < need:
        log_clutter_pmf = np.concatenate(
            [log_clutter_pmf, np.full(need - len(log_clutter_pmf), NEG_INF)])
    log_pc_fact = log_clutter_pmf[:need] + lf[:need]
    n_idx = np.arange(n_max + 1)
    with np.errstate(divide='ignore'):
        log_n = np.log(n_idx)

    def shifted(lam):          # log Lambda(n - 1) at n = 0..N_max (-inf at n = 0)
        return np.concatenate([[NEG_INF], lam[:-1]])

    lam_P = []                 # log Lambda_P(n) per partition
    lam_PW = []                # per partition: (cells, log Lambda_{P minus W}(n)) rows
    for cells in partitions:
        cells = np.asarray(cells)
        single = cell_size[cells] == 1
        s_cells = cells[single]
        ns_cells = cells[~single]
        k1, k2 = len(s_cells), len(ns_cells)
        log_A = float(np.sum(log_a[ns_cells]))
        s_a = log_a[s_cells]
        active = np.isfinite(s_a)
        s_act = s_cells[active]
        e = log_esf(s_a[active])
        lam = _log_lambda(T, log_pc_fact, log_A, k1, k2, e) if np.isfinite(log_A) else \
            np.full(n_max + 1, NEG_INF)
        lam_P.append(lam)
        rows_cells = []
        rows = []
        # removing a non-singleton cell W: A_P / a_W, one fewer non-singleton
        for c in ns_cells:
            if not np.isfinite(log_a[c]):
                continue
            log_A_w = float(np.sum(log_a[ns_cells[ns_cells != c]]))
            rows_cells.append(c)
            rows.append(_log_lambda(T, log_pc_fact, log_A_w, k1, k2 - 1, e))
        # removing an active singleton: leave-one-out symmetric functions
        if len(s_act) and np.isfinite(log_A):
            e_loo = log_esf_leave_one_out(s_a[active])
            for row, c in enumerate(s_act):
                rows_cells.append(c)
                rows.append(_log_lambda(T, log_pc_fact, log_A, k1 - 1, k2, e_loo[row]))
        lam_PW.append((np.asarray(rows_cells, dtype=np.int64),
                       np.array(rows).reshape(len(rows), n_max + 1)))

    lam_P = np.array(lam_P).reshape(len(partitions), n_max + 1)
    per_partition = logsumexp(lam_P + log_card[None, :], axis=1)
    log_L = logsumexp(per_partition)
    log_part_weight = per_partition - log_L
    # Upsilon_0 = sum_n n p(n) sum_P Lambda_P(n-1) / (Nbar L)
    lam_sum_shift = shifted(logsumexp(lam_P, axis=0)) if len(partitions) else \
        np.full(n_max + 1, NEG_INF)
    log_u0 = logsumexp(log_n + log_card + lam_sum_shift) - log_nbar - log_L
    log_card_post = log_card + logsumexp(lam_P, axis=0) - log_L

    # Upsilon_{P,W}, summed over the partitions holding W
    log_u_cell = np.full(n_cells, NEG_INF)
    for cells_w, rows in lam_PW:
        if not len(cells_w):
            continue
        rows_shift = np.concatenate([np.full((len(rows), 1), NEG_INF), rows[:, :-1]], axis=1)
        u = logsumexp(log_n[None, :] + log_card[None, :] + rows_shift, axis=1) - log_nbar - log_L
        log_u_cell[cells_w] = np.logaddexp(log_u_cell[cells_w], u)

    log_w_missed = log_w + log_qd + log_u0
    log_w_det = log_w[:, None] + log_g - cell_log_c[None, :] + log_u_cell[None, :]
    return UpdateWeights(log_w_missed, log_w_det, log_card_post, log_part_weight)


def phd_update(log_w, log_qd, log_g, cell_log_c, cell_size, partitions, clutter_rate,
               n_max) -> UpdateWeights:
    """
    ET-PHD update (Granström, Lundquist & Orguner 2012) in the log domain.

    Notes
    -----
    ``omega_P ~ prod_{W in P} d_W``, ``d_W = delta_{|W|,1} + sum_i w_i g_iW / prod lambda c(z)``;
    detected weight ``sum_{P ni W} omega_P w_i g_iW / (d_W prod lambda c(z))``; missed
    weight ``w_i q_D,i``. ``cell_log_c`` is ``log c^W`` and ``lambda`` the clutter rate.
    The posterior cardinality returned is Poisson with the posterior mean (the PHD
    carries no more than that).

    """
    log_w = np.asarray(log_w, dtype=float)
    n_comp, n_cells = log_g.shape
    log_lc = cell_log_c + cell_size * np.log(clutter_rate)      # log prod lambda c(z)
    if n_comp:
        log_sum = logsumexp(log_w[:, None] + log_g, axis=0) - log_lc
    else:
        log_sum = np.full(n_cells, NEG_INF)
    log_d = np.logaddexp(np.where(cell_size == 1, 0.0, NEG_INF), log_sum)
    log_omega = np.array([np.sum(log_d[np.asarray(c)]) for c in partitions])
    log_omega = log_omega - logsumexp(log_omega)
    log_cell_weight = np.full(n_cells, NEG_INF)
    for lo, cells in zip(log_omega, partitions):
        cells = np.asarray(cells)
        log_cell_weight[cells] = np.logaddexp(log_cell_weight[cells], lo)
    with np.errstate(invalid='ignore'):
        factor = np.where(np.isfinite(log_cell_weight), log_cell_weight - log_d - log_lc, NEG_INF)
    log_w_det = log_w[:, None] + log_g + factor[None, :]
    log_w_missed = log_w + log_qd
    total = logsumexp(np.concatenate([log_w_missed, log_w_det.ravel()])) if n_comp else NEG_INF
    mean = float(np.exp(total)) if np.isfinite(total) else 0.0
    card = poisson_log_pmf(mean, n_max)
    card = card - logsumexp(card)
    return UpdateWeights(log_w_missed, log_w_det, card, log_omega)


def predict_cardinality(log_card: np.ndarray, p_survival: float, birth_mean: float
                        ) -> np.ndarray:
    """
    Predicted cardinality: binomial thinning by survival, then Poisson birth, truncated.

    Notes
    -----
    ``p+(n) = sum_j p_B(n - j) sum_{l >= j} C(l, j) p_S^j (1 - p_S)^{l - j} p(l)``;
    the mass beyond ``N_max`` is dropped and the pmf renormalised.

    """
    n_max = len(log_card) - 1
    lf = gammaln(np.arange(n_max + 1) + 1)
    j = np.arange(n_max + 1)[:, None]
    l_ = np.arange(n_max + 1)[None, :]
    valid = j <= l_
    lj = np.where(valid, l_ - j, 0)
    log_comb = lf[l_] - lf[j] - lf[lj]
    with np.errstate(divide='ignore', invalid='ignore'):
        log_ps = np.log(p_survival)
        log_qs = np.log1p(-p_survival) if p_survival < 1 else NEG_INF
        term = np.where(j > 0, j * log_ps, 0.0) + np.where(lj > 0, lj * log_qs, 0.0)
    surv = np.where(valid, log_comb + term + log_card[None, :], NEG_INF)
    log_surv = logsumexp(surv, axis=1)
    log_birth = poisson_log_pmf(birth_mean, n_max)
    n = np.arange(n_max + 1)
    # convolution: out[n] = logsumexp_j surv[j] + birth[n - j]
    diff = n[:, None] - n[None, :]
    conv = np.where(diff >= 0, log_surv[None, :] + log_birth[np.clip(diff, 0, None)], NEG_INF)
    out = logsumexp(conv, axis=1)
    return out - logsumexp(out)
