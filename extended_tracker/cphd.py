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
import math

import numpy as np
from scipy.special import gammaln

from .logmath import logsumexp, lse1, lse_last
from .tables import cached_tables

NEG_INF = -np.inf
# partitions are split into three batches by active singletons from these sizes on
BATCH_MIN_PARTITIONS = 6
BATCH_MIN_SINGLETONS = 12


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
    possible : bool
        False when no partition can explain the detections (every one holds more
        detected objects than the cardinality allows, or a cell of several detections
        nothing explains): then the scan carries no usable likelihood, and the weights
        are the predicted ones, the cardinality the predicted pmf, no cell detected.

    """

    log_w_missed: np.ndarray
    log_w_detected: np.ndarray
    log_card: np.ndarray
    log_partition_weight: np.ndarray
    possible: bool = True


def _prediction_stands(log_w, n_cells: int, log_card, n_part: int) -> UpdateWeights:
    """The update of a scan no partition explains: the prediction, unchanged."""
    return UpdateWeights(np.array(log_w, dtype=float), np.full((len(log_w), n_cells), NEG_INF),
                         np.array(log_card, dtype=float), np.full(n_part, NEG_INF), False)


def poisson_log_pmf(mean: float, n_max: int) -> np.ndarray:
    """Log Poisson pmf at ``0..n_max`` (untruncated values)."""
    n = np.arange(n_max + 1)
    if mean <= 0:
        out = np.full(n_max + 1, -np.inf)
        out[0] = 0.0
        return out
    return n * np.log(mean) - mean - _log_factorial(n_max)


def _log_factorial(k: int) -> np.ndarray:
    """``log(i!)`` for ``i = 0..k`` (a cached table grown on demand)."""
    global _LF
    if len(_LF) <= k:
        _LF = gammaln(np.arange(max(k + 1, 2 * len(_LF))) + 1.0)
    return _LF[:k + 1]


_LF = gammaln(np.arange(256) + 1.0)


@cached_tables(maxsize=256)
def _log_falling(n_max: int, j_max: int):
    """``log(n!/(n-j)!)`` (``-inf`` for ``j > n``) and ``max(n - j, 0)`` as (n, j) tables."""
    n = np.arange(n_max + 1)[:, None]
    j = np.arange(j_max + 1)[None, :]
    lf = _log_factorial(n_max + 1)
    valid = j <= n
    nj = np.where(valid, n - j, 0)
    return np.where(valid, lf[n] - lf[nj], NEG_INF), nj


@cached_tables(maxsize=16)
def _log_counts(n_max: int) -> np.ndarray:
    """``log n`` for ``n = 0..N_max`` (``-inf`` at 0)."""
    with np.errstate(divide='ignore'):
        return np.log(np.arange(n_max + 1))


def _log_lambda_table(log_q0: float, n_max: int, j_max: int) -> np.ndarray:
    """``T[n, j] = log(n!/(n-j)!) + (n-j) log q0`` for ``j <= n``, else ``-inf``."""
    falling, nj = _log_falling(n_max, j_max)
    if log_q0 == NEG_INF:
        # 0 * log q0 must be 0 even when q0 = 0
        return np.where(nj > 0, NEG_INF, falling)
    return falling + nj * log_q0


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


def _inf_padded(table: np.ndarray, pad: int) -> np.ndarray:
    """``table`` with ``pad`` entries of ``-inf`` on each side: ``out[i + pad]`` is
    ``table[i]`` for ``i`` in range and ``-inf`` for ``-pad <= i < len(table) + pad``."""
    out = np.full(len(table) + 2 * pad, -np.inf)
    out[pad:pad + len(table)] = table
    return out


def _sum_tables(T: np.ndarray, W1: np.ndarray, pad: int) -> np.ndarray:
    """
    The tables the partition terms read by column ``j = k2 + r``, stacked and padded by
    ``pad`` columns of ``-inf`` on each side (``out[:, pad + j]``): rows ``0..N_max`` are
    ``T[n, j]``, row ``N_max + 1`` is ``W1[j]`` and row ``N_max + 2`` is ``W1[j - 1]``.
    """
    n_rows, width = T.shape
    out = np.full((n_rows + 2, width + 2 * pad), -np.inf)
    out[:n_rows, pad:pad + width] = T
    out[n_rows, pad:pad + width] = W1
    out[n_rows + 1, pad + 1:pad + 1 + width] = W1
    return out


def _partition_terms(parts: list, Z: np.ndarray, pc_pad: np.ndarray, pad: int):
    """
    ``Lambda_P(n)``, the ``Upsilon_0`` term and the per-cell ``Upsilon`` terms of a batch
    of partitions, all at once.

    ``parts`` holds one tuple a partition (:func:`_partition_rows`): ``k1``, ``k2``,
    ``log A_P``, the log-values and cells of its active singletons, and its non-singleton
    cells with their ``log a_W``. ``Z`` is :func:`_sum_tables` and ``pc_pad`` the table
    ``(k-j)! p_c(k-j)``, both padded by ``pad`` (more than any partition's active
    singletons). Returns ``lam (p, N_max + 1)``, ``u0 (p,)`` and ``(cells, values)`` to
    add into the cells' log-Upsilon, the non-singleton cells first, each group in the
    partitions' order.

    Notes
    -----
    Every term is a sum over ``r`` (active singletons detected) of a table entry at
    ``k2 + r`` times ``pc_r = (k1 - r)! p_c(k1 - r) e_r(a_S)``: ``Lambda_P(n)`` reads
    ``T[n]``, ``Upsilon_0`` reads ``W1`` and a non-singleton cell's term ``W1`` one column
    left (one non-singleton fewer), so the three are one gather and one log-sum.
    """
    n_part = len(parts)
    k1 = np.array([q[0] for q in parts], dtype=np.int64)
    k2 = np.array([q[1] for q in parts], dtype=np.int64)
    log_A = np.array([q[2] for q in parts])
    feasible = log_A > NEG_INF
    ka = [len(q[3]) for q in parts]
    R = max(ka, default=0)
    # the active singletons of each partition (a feasible one's, from which some object may
    # have come) packed into rows padded with -inf
    S = np.array([q[3] + [NEG_INF] * (R - len(q[3])) for q in parts]).reshape(n_part, R)
    r = np.arange(R + 1)
    G = Z[:, pad + k2[:, None] + r]                     # (N_max + 3, p, R + 1)
    pcg = pc_pad[pad + k1[:, None] - r]                 # (k1 - r)! p_c(k1 - r)
    B = None
    if R:
        # coefficients of the leave-one-out sums (W an active singleton, below):
        # W1[k2 + r] (k1 - 1 - r)! p_c(k1 - 1 - r) for r < ka
        B = G[-2, :, :R] + pcg[:, 1:]
        B[r[:R] >= np.array(ka)[:, None]] = NEG_INF
    log_e, loo = esf_terms(S, B)                        # e_r(a_S), leave-one-out sums
    pc_r = pcg + log_e
    pc_r[~feasible] = NEG_INF
    sums = lse_last(G + pc_r)                           # (N_max + 3, p)
    lam = log_A[:, None] + sums[:-2].T
    u0 = log_A + sums[-2]
    # W non-singleton: Lambda of P without W is A_P / a_W with one non-singleton fewer;
    # W an active singleton: one singleton fewer, e_r of the others (leave one out)
    ns_part, ns_cell, ns_la, act_part, act_slot, act_cell = [], [], [], [], [], []
    for i, (_, _, a, act_la, act_cells, cells, la) in enumerate(parts):
        if a > NEG_INF:
            ns_part += [i] * len(cells)
            ns_cell += cells
            ns_la += la
        act_part += [i] * len(act_cells)
        act_slot += range(len(act_cells))
        act_cell += act_cells
    vals = []
    if ns_cell:
        pr = np.array(ns_part, dtype=np.int64)
        vals.append(log_A[pr] - np.array(ns_la) + sums[-1][pr])
    if act_cell:
        pa = np.array(act_part, dtype=np.int64)
        vals.append(log_A[pa] + loo[pa, np.array(act_slot, dtype=np.int64)])
    if not vals:
        return lam, u0, np.zeros(0, dtype=np.int64), np.zeros(0)
    cells = np.array(ns_cell + act_cell, dtype=np.int64)
    return lam, u0, cells, vals[0] if len(vals) == 1 else np.concatenate(vals)


def _partition_rows(partitions, log_a, cell_size, clutter_cells):
    """
    Each partition's counts and cells for :func:`_partition_terms`, in Python (a scan has a
    few partitions of a few cells): ``(k1, k2, log A_P, active log a_W, active cells,
    non-singleton cells, their log a_W)``.

    ``k1`` counts singletons (a clutter cell as its detections), ``k2`` the other cells;
    ``A_P`` is the product of the non-singletons' ``a_W``, summed in cell order from 0
    (``-inf`` makes the partition infeasible: its singletons count as inactive); an active
    singleton is one some object may have produced (``a_W`` finite).
    """
    la_all, size_all = log_a.tolist(), cell_size.tolist()
    clutter = clutter_cells.tolist() if clutter_cells is not None else None
    out = []
    for part in partitions:
        k1 = k2 = 0
        log_A = 0.0
        act_la, act_cells, cells, las = [], [], [], []
        for c in np.asarray(part).tolist():
            if clutter is not None and clutter[c]:
                # a clutter cell is its detections as singletons no component explains
                k1 += size_all[c]
            elif size_all[c] == 1:
                k1 += 1
                if la_all[c] > NEG_INF:
                    act_la.append(la_all[c])
                    act_cells.append(c)
            else:
                k2 += 1
                log_A += la_all[c]
                cells.append(c)
                las.append(la_all[c])
        if log_A == NEG_INF:
            # a non-singleton cell no object explains makes the partition impossible
            # (clutter is singletons only): it contributes nothing
            act_la, act_cells = [], []
        out.append((k1, k2, log_A, act_la, act_cells, cells, las))
    return out


def cphd_update(log_w, log_qd, log_g, cell_log_c, cell_size, partitions, log_card,
                log_clutter_pmf, clutter_cells=None) -> UpdateWeights:
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
        Clutter cardinality pmf (log), ``M`` larger than the most cells in a partition
        (counting a clutter cell as its detections).
    clutter_cells : (c,) bool array, optional
        Cells of several detections that no component explains, each taken as that many
        clutter detections: the partition holding one is evaluated as the partition with
        it split into singletons that no component explains. Clutter comes one detection
        at a time, so without this such a cell makes every partition holding it
        impossible.

    Returns
    -------
    UpdateWeights

    """
    log_w = np.asarray(log_w, dtype=float)
    n_comp, n_cells = log_g.shape
    n_max = len(log_card) - 1
    n_part = len(partitions)
    if not n_part:
        return _prediction_stands(log_w, n_cells, log_card, 0)
    log_nbar = NEG_INF
    if n_comp:
        # log N-bar, log q0 N-bar and every cell's log psi_W N-bar, psi_W N-bar =
        # sum_i w_i g_iW: log-sums over the components, one row each
        table = np.empty((n_cells + 2, n_comp))
        table[0] = log_w
        np.add(log_w, log_qd, out=table[1])
        np.add(log_w, log_g.T, out=table[2:])
        sums = lse_last(table)
        log_nbar = float(sums[0])
    if log_nbar == NEG_INF:
        # no predicted objects: only clutter explains the scan
        log_nbar = 0.0
        log_q0 = 0.0
        log_psi = np.full(n_cells, -np.inf)
    else:
        log_q0 = float(sums[1]) - log_nbar
        log_psi = sums[2:] - sums[0, ...]      # log_nbar, as a 0-d operand
    # log a_W = log(psi_W / c^W)
    log_a = log_psi - cell_log_c
    parts = _partition_rows(partitions, log_a, cell_size, clutter_cells)
    # the most cells of a partition, a clutter cell counted as its detections
    k_most = max(q[0] + q[1] for q in parts)
    T = _log_lambda_table(log_q0, n_max, k_most)
    lf = _log_factorial(k_most + 1)
    need = k_most + 1
    if len(log_clutter_pmf) < need:
        log_clutter_pmf = np.concatenate(
            [log_clutter_pmf, np.full(need - len(log_clutter_pmf), NEG_INF)])
    log_pc_fact = log_clutter_pmf[:need] + lf[:need]
    log_n = _log_counts(n_max)

    # W1[j] = log sum_{n>=1} n p(n) n'!/(n'-j)! q0^{n'-j} at n' = n - 1: folds the n-sum of
    # every Upsilon into one table, so each partition and cell costs a scalar logsumexp.
    W1 = lse_last((log_n[1:, None] + log_card[1:, None] + T[:-1, :]).T)
    log_u_cell = np.full(n_cells, -np.inf)
    ka = [len(q[3]) for q in parts]
    R = max(ka)
    pad = R + 1
    Z = _sum_tables(T, W1, pad)
    pc_pad = _inf_padded(log_pc_fact, pad)
    # Partitions are batched by their number of active singletons (terciles when
    # there are many): a batch costs its size times its largest count squared, so
    # padding a 5-singleton partition to 55 would waste most of the work.
    if n_part >= BATCH_MIN_PARTITIONS and R >= BATCH_MIN_SINGLETONS:
        lam_P = np.full((n_part, n_max + 1), -np.inf)
        u0_terms = np.full(n_part, -np.inf)
        ka = np.array(ka)
        bucket = np.quantile(ka, [1 / 3, 2 / 3]).searchsorted(ka, side='left')
        for b in np.unique(bucket).tolist():
            sel = (bucket == b).nonzero()[0]
            lam_P[sel], u0_terms[sel], cells, vals = _partition_terms(
                [parts[i] for i in sel.tolist()], Z, pc_pad, pad)
            np.logaddexp.at(log_u_cell, cells, vals)
    else:
        # one batch: every partition, no selection to make
        lam_P, u0_terms, cells, vals = _partition_terms(parts, Z, pc_pad, pad)
        np.logaddexp.at(log_u_cell, cells, vals)

    per_partition = lse_last(lam_P + log_card[None, :])
    log_L = lse1(per_partition)
    if log_L == NEG_INF:
        return _prediction_stands(log_w, n_cells, log_card, n_part)
    log_part_weight = per_partition - log_L
    log_u0 = lse1(u0_terms) - log_nbar - log_L
    log_u_cell = log_u_cell - log_nbar - log_L
    log_card_post = log_card + lse_last(lam_P.T) - log_L

    log_w_missed = log_w + log_qd + log_u0
    log_w_det = log_w[:, None] + log_g - cell_log_c[None, :] + log_u_cell[None, :]
    return UpdateWeights(log_w_missed, log_w_det, log_card_post, log_part_weight)


def phd_update(log_w, log_qd, log_g, cell_log_c, cell_size, partitions, clutter_rate,
               n_max, clutter_cells=None) -> UpdateWeights:
    """
    ET-PHD update (Granström, Lundquist & Orguner 2012) in the log domain.

    Notes
    -----
    ``omega_P ~ prod_{W in P} d_W``, ``d_W = delta_{|W|,1} + sum_i w_i g_iW / prod lambda c(z)``;
    detected weight ``sum_{P ni W} omega_P w_i g_iW / (d_W prod lambda c(z))``; missed
    weight ``w_i q_D,i``. ``cell_log_c`` is ``log c^W`` and ``lambda`` the clutter rate.
    The posterior cardinality returned is Poisson with the posterior mean (the PHD
    carries no more than that). A cell of ``clutter_cells`` (see :func:`cphd_update`) is
    its detections as singletons no component explains: ``d_W = 1``, as for each of them.

    """
    log_w = np.asarray(log_w, dtype=float)
    n_comp, n_cells = log_g.shape
    log_lc = cell_log_c + cell_size * np.log(clutter_rate)      # log prod lambda c(z)
    if n_comp:
        log_sum = logsumexp(log_w[:, None] + log_g, axis=0) - log_lc
    else:
        log_sum = np.full(n_cells, -np.inf)
    clutter_only = cell_size == 1 if clutter_cells is None else (cell_size == 1) | clutter_cells
    log_d = np.logaddexp(np.where(clutter_only, 0.0, NEG_INF), log_sum)
    log_omega = np.array([np.sum(log_d[np.asarray(c)]) for c in partitions])
    log_total = logsumexp(log_omega)
    if log_total == NEG_INF:
        card = poisson_log_pmf(float(np.exp(logsumexp(log_w))) if n_comp else 0.0, n_max)
        return _prediction_stands(log_w, n_cells, card - logsumexp(card), len(partitions))
    log_omega = log_omega - log_total
    log_cell_weight = np.full(n_cells, -np.inf)
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
    (:func:`_predict_cardinality_log`) stands in. ``p_S`` changes with every scan
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
            p = (p_s / q_s) ** n * (_binomials(n_max) @ (q_s ** n * p))
        else:
            log_comb, j, lj = _thinning_terms(n_max)
            p = np.exp(log_comb + (j * np.log(p_s) + lj * np.log1p(-p_s))) @ p
    mean = float(birth_mean)
    birth = np.empty(n_max + 1)
    birth[0] = 1.0
    if mean > 0.0:
        top = min(int(mean), n_max)                    # the largest mean^k / k! up to N_max
        if top * math.log(mean) - math.lgamma(top + 1) > 700.0:
            return _predict_cardinality_log(log_card, p_s, mean)
        np.cumprod(mean / n[1:], out=birth[1:])
    else:
        birth[1:] = 0.0
    out = np.convolve(p, birth)[:n_max + 1]
    total = np.sum(out)
    if not (0.0 < total < np.inf):
        return _predict_cardinality_log(log_card, p_s, mean)
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
def _binomials(n_max: int) -> np.ndarray:
    """``C(l, j)`` as a (j, l) table of floats (0 for ``j > l``), each exactly rounded."""
    return np.array([[float(math.comb(l_, j)) for l_ in range(n_max + 1)]
                     for j in range(n_max + 1)])


def _predict_cardinality_log(log_card: np.ndarray, p_s: float, birth_mean: float
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
    two tracks are found to be one object (``identity.join_pairs``).

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
    lf = _log_factorial(n_max)
    j, l_ = n[:, None], n[None, :]
    valid = j <= l_
    lj = np.where(valid, l_ - j, 0)
    log_comb = np.where(valid, lf[l_] - lf[j] - lf[lj], NEG_INF)
    return log_comb, j.astype(float), lj.astype(float)
