"""
Mixture reduction: pruning, GGIW merging by moment matching, capping.

Notes
-----
Gamma merge: match ``E[gamma]`` and ``E[log gamma]`` (Granström & Orguner, "Estimation
and maintenance of measurement rates for multiple extended target tracking", FUSION 2012).
Inverse Wishart merge: match ``E[X^-1]`` and ``E[log|X|]`` (Granström & Orguner, "On the
reduction of Gaussian inverse Wishart mixtures", FUSION 2012); ``v`` solves a scalar
equation, by bisection here (monotone, vectorised).

"""

from __future__ import annotations

import numpy as np
from scipy.special import digamma, polygamma

from .ggiw import D, inv2, IW_OFFSET, logdet_spd2, Mixture, symmetrize


def merge_gamma(w, alpha, beta):
    """
    Moment-matched Gamma of a weighted Gamma mixture (``w`` normalised inside).

    Solves ``log a - digamma(a) = log E[g] - E[log g]`` for the shape by Newton steps.
    """
    wn = w / w.sum()
    mean = np.sum(wn * alpha / beta)
    elog = np.sum(wn * (digamma(alpha) - np.log(beta)))
    c = np.log(mean) - elog            # >= 0 by Jensen
    if c <= 1e-12:
        a = float(np.sum(wn * alpha))
        return a, a / mean
    a = (3 - c + np.sqrt((c - 3) ** 2 + 24 * c)) / (12 * c)     # Minka's starting point
    for _ in range(20):
        f = np.log(a) - digamma(a) - c
        fp = 1 / a - polygamma(1, a)
        step = f / fp
        a_new = a - step
        if a_new <= 0:
            a_new = a / 2
        if abs(a_new - a) < 1e-12 * a:
            a = a_new
            break
        a = a_new
    return float(a), float(a / mean)


def _iw_psi_sum(nu):
    """``sum_{j=1}^{d} digamma((nu - j + 1) / 2)`` (vectorised)."""
    return sum(digamma((nu - j + 1) / 2) for j in range(1, D + 1))


def merge_iw(w, v, V):
    """
    Moment-matched inverse Wishart (Koch's ``v``, ``V``) of a weighted IW mixture.

    Notes
    -----
    With ``nu = v - d - 1``: ``E[X^-1] = nu V^-1`` and
    ``E[log|X|] = log|V| - d log 2 - sum_j digamma((nu - j + 1)/2)``. Matching both gives
    ``V = nu Psi^-1`` with ``Psi = sum w_i nu_i V_i^-1`` and
    ``d log nu - sum_j digamma((nu-j+1)/2) = c + log|Psi| + d log 2``; the left side decreases
    in ``nu``, so bisection finds it.

    """
    wn = w / w.sum()
    nu_i = v - D - 1
    Psi = np.sum(wn[:, None, None] * nu_i[:, None, None] * inv2(V), axis=0)
    elog = np.sum(wn * (logdet_spd2(V) - D * np.log(2) - _iw_psi_sum(nu_i)))
    target = elog + logdet_spd2(Psi) + D * np.log(2)

    def lhs(nu):
        return D * np.log(nu) - _iw_psi_sum(nu)

    # Newton on lhs(nu) = target; lhs is decreasing and convex in nu, so Newton from the
    # left of the root is monotone. Start at the smallest allowed nu's neighbourhood and
    # keep iterates inside (nu_min, inf).
    nu_min = IW_OFFSET - D - 1 + 1e-9                 # nu > d + 1 keeps v > 2d + 2
    if lhs(nu_min) <= target:
        nu = nu_min
    else:
        nu = float(np.min(nu_i))
        if lhs(nu) < target:
            nu = nu_min + 1e-6
        for _ in range(50):
            f = lhs(nu) - target
            fp = D / nu - 0.5 * sum(polygamma(1, (nu - j + 1) / 2) for j in range(1, D + 1))
            step = f / fp
            nu_new = nu - step
            if nu_new <= nu_min:
                nu_new = 0.5 * (nu + nu_min)
            if abs(nu_new - nu) <= 1e-12 * nu:
                nu = nu_new
                break
            nu = nu_new
    V_new = nu * inv2(Psi)
    return float(nu + D + 1), symmetrize(V_new)


def merge_components(mix: Mixture, idx: np.ndarray):
    """Merge components ``idx`` into one; weight is the sum, label that of the heaviest."""
    w = mix.w[idx]
    W = w.sum()
    wn = w / W
    m = np.sum(wn[:, None] * mix.m[idx], axis=0)
    dm = mix.m[idx] - m
    P = np.sum(wn[:, None, None] * (mix.P[idx] + dm[:, :, None] * dm[:, None, :]), axis=0)
    a, b = merge_gamma(w, mix.alpha[idx], mix.beta[idx])
    v, V = merge_iw(w, mix.v[idx], mix.V[idx])
    label = mix.label[idx][np.argmax(w)]
    return W, a, b, m, symmetrize(P), v, V, label


def reduce_mixture(mix: Mixture, prune_weight: float, merge_distance: float,
                   max_components: int) -> tuple[Mixture, int]:
    """
    Prune, merge close components of the same label, cap the count.

    Returns
    -------
    mixture : Mixture
    capped : int
        Components dropped by the cap.

    Notes
    -----
    Greedy merging as in GM-PHD filters, restricted to one label so that two crossing
    objects are never fused: the heaviest remaining component absorbs those of its label
    within squared Mahalanobis distance ``merge_distance`` of its position.

    """
    keep = mix.w >= prune_weight
    mix = mix.take(keep)
    if not len(mix):
        return mix, 0
    out = []
    for lab in np.unique(mix.label):
        idx = np.flatnonzero(mix.label == lab)
        if len(idx) == 1:
            out.append(idx)
            continue
        remaining = idx[np.argsort(-mix.w[idx], kind='stable')]
        while len(remaining):
            j = remaining[0]
            e = mix.m[remaining, :2] - mix.m[j, :2]
            Pi = inv2(mix.P[j, :2, :2])
            d2 = np.einsum('ki,ij,kj->k', e, Pi, e)
            group = remaining[d2 <= merge_distance]
            out.append(group)
            remaining = remaining[d2 > merge_distance]
    parts = []
    for group in out:
        if len(group) == 1:
            parts.append(mix.take(group))
        else:
            W, a, b, m, P, v, V, lab = merge_components(mix, group)
            parts.append(Mixture(np.array([W]), np.array([a]), np.array([b]), m[None], P[None],
                                 np.array([v]), V[None], np.array([lab], dtype=np.int64)))
    merged = Mixture.concat(parts)
    capped = 0
    if len(merged) > max_components:
        order = np.argsort(-merged.w, kind='stable')[:max_components]
        capped = len(merged) - max_components
        merged = merged.take(np.sort(order))
    return merged, capped
