"""
The multiple extended object update over partitions (ET-CPHD and its ET-PHD special case).

Everything here works on log-weights and log-likelihoods; no GGIW detail enters, so the
same code is tested exactly against brute-force multi-object Bayes on a discrete world.

Notes
-----
Section 4 of ``doc/model.md``; Lundquist, Granström & Orguner, IEEE JSTSP 7(3), 2013
(ET-CPHD) and Granström, Lundquist & Orguner, IEEE TAES 48(4), 2012 (ET-PHD). For a
partition ``P`` with ``k`` cells, ``k2`` of them non-singleton::

    Lambda_P(n) = A_P sum_{j=k2}^{min(k,n)} (k-j)! p_c(k-j) n!/(n-j)! q0^{n-j} e_{j-k2}(a_S)

with ``A_P`` the product of ``a_W`` over non-singleton cells and ``e_r`` the elementary
symmetric function over the singleton cells.

"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .cardinality import log_factorial, poisson_log_pmf
from .esf import esf_terms
from .logmath import logsumexp, lse1, lse_last, NEG_INF
from .tables import cached_tables

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


@cached_tables(maxsize=256)
def _log_falling(n_max: int, j_max: int):
    """``log(n!/(n-j)!)`` (``-inf`` for ``j > n``) and ``max(n - j, 0)`` as (n, j) tables."""
    n = np.arange(n_max + 1)[:, None]
    j = np.arange(j_max + 1)[None, :]
    lf = log_factorial(n_max + 1)
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


def _predicted_sums(log_w, log_qd, log_g):
    """
    ``(log N-bar, log q0, log psi_W)``: the predicted mean count, the mean miss factor and
    every cell's ``psi_W = sum_i w_i g_iW / N-bar`` (0, 0 and ``-inf`` with no predicted
    objects: only clutter explains the scan).
    """
    n_comp, n_cells = log_g.shape
    if n_comp:
        # log-sums over the components, one row each: N-bar, q0 N-bar, psi_W N-bar
        table = np.empty((n_cells + 2, n_comp))
        table[0] = log_w
        np.add(log_w, log_qd, out=table[1])
        np.add(log_w, log_g.T, out=table[2:])
        sums = lse_last(table)
        if sums[0] != NEG_INF:
            log_nbar = float(sums[0])
            return log_nbar, float(sums[1]) - log_nbar, sums[2:] - sums[0]
    return 0.0, 0.0, np.full(n_cells, -np.inf)


def _all_partition_terms(parts, T, W1, log_pc_fact, n_cells: int):
    """
    Every partition's ``Lambda_P(n)`` row, miss term and detection terms summed per cell
    (:func:`_partition_terms`).

    Partitions are batched by their number of active singletons (terciles when there are
    many): a batch costs its size times its largest count squared, so padding a
    5-singleton partition to 55 would waste most of the work.
    """
    n_part, n_max = len(parts), T.shape[0] - 1
    log_u_cell = np.full(n_cells, -np.inf)
    ka = [len(q[3]) for q in parts]
    R = max(ka)
    pad = R + 1
    Z = _sum_tables(T, W1, pad)
    pc_pad = _inf_padded(log_pc_fact, pad)
    if n_part < BATCH_MIN_PARTITIONS or R < BATCH_MIN_SINGLETONS:
        lam_P, u0_terms, cells, vals = _partition_terms(parts, Z, pc_pad, pad)
        np.logaddexp.at(log_u_cell, cells, vals)
        return lam_P, u0_terms, log_u_cell
    lam_P = np.full((n_part, n_max + 1), -np.inf)
    u0_terms = np.full(n_part, -np.inf)
    ka = np.array(ka)
    bucket = np.quantile(ka, [1 / 3, 2 / 3]).searchsorted(ka, side='left')
    for b in np.unique(bucket).tolist():
        sel = (bucket == b).nonzero()[0]
        lam_P[sel], u0_terms[sel], cells, vals = _partition_terms(
            [parts[i] for i in sel.tolist()], Z, pc_pad, pad)
        np.logaddexp.at(log_u_cell, cells, vals)
    return lam_P, u0_terms, log_u_cell


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
    log_nbar, log_q0, log_psi = _predicted_sums(log_w, log_qd, log_g)
    # log a_W = log(psi_W / c^W)
    log_a = log_psi - cell_log_c
    parts = _partition_rows(partitions, log_a, cell_size, clutter_cells)
    # the most cells of a partition, a clutter cell counted as its detections
    k_most = max(q[0] + q[1] for q in parts)
    T = _log_lambda_table(log_q0, n_max, k_most)
    lf = log_factorial(k_most + 1)
    need = k_most + 1
    if len(log_clutter_pmf) < need:
        log_clutter_pmf = np.concatenate(
            [log_clutter_pmf, np.full(need - len(log_clutter_pmf), NEG_INF)])
    log_pc_fact = log_clutter_pmf[:need] + lf[:need]
    log_n = _log_counts(n_max)

    # W1[j] = log sum_{n>=1} n p(n) n'!/(n'-j)! q0^{n'-j} at n' = n - 1: folds the n-sum of
    # every Upsilon into one table, so each partition and cell costs a scalar logsumexp.
    W1 = lse_last((log_n[1:, None] + log_card[1:, None] + T[:-1, :]).T)
    lam_P, u0_terms, log_u_cell = _all_partition_terms(parts, T, W1, log_pc_fact, n_cells)
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
