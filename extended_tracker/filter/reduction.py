"""
Mixture reduction: pruning, GGIW merging by moment matching, capping.

Notes
-----
Gamma merge: match ``E[gamma]`` and ``E[log gamma]`` (Granström & Orguner, "Estimation
and maintenance of measurement rates for multiple extended target tracking", FUSION 2012).
Inverse Wishart merge: match ``E[X^-1]`` and ``E[log|X|]`` (Granström & Orguner, "On the
reduction of Gaussian inverse Wishart mixtures", FUSION 2012); ``v`` solves a scalar
equation (monotone) by bracketed Newton steps, vectorised over the merges.

"""

from __future__ import annotations

import numpy as np
from scipy.special import digamma, zeta

from .algebra2 import eig2, inv2, logdet_spd2, symmetrize
from .mixture import D, IW_OFFSET, Mixture, weight_key

ABSORB_RATIO = 0.01     # lighter members are absorbed into their label's head
MEAN_EXTENT_RATIO = 2.0  # a merged E[X] may exceed the members' mean E[X] this much (trace)
MIN_SEMI_AXIS = 0.01     # m: merged extents keep at least this semi-axis (see _floor_extent)


def _trigamma(x):
    """``polygamma(1, x)``, called as the Hurwitz zeta ``zeta(2, x)`` it evaluates (the same
    values, without polygamma's Python wrapper, which also evaluates digamma)."""
    return zeta(2.0, x)


_TINY = np.finfo(float).tiny


def _gamma_shape_start(c):
    """
    Minka's starting point for the shape ``a`` of ``log a - digamma(a) = c`` (c > 0),
    ``(3 - c + r) / (12 c)`` with ``r = sqrt((c - 3)^2 + 24 c)``, taken for ``c >= 3`` as
    the equal ``2 / (r + c - 3)``: there ``3 - c + r`` cancels (to 0 once ``c`` passes
    some 1e16, as for a rate whose shape forgetting drove towards 0).
    """
    d = c - 3.0
    r = np.sqrt(d * d + 24.0 * c)
    return np.where(c < 3.0, (3.0 - c + r) / (12.0 * c), 2.0 / (r + c - 3.0))


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
    a = float(_gamma_shape_start(c))
    for _ in range(20):
        f = np.log(a) - digamma(a) - c
        fp = 1 / a - _trigamma(a)
        step = f / fp
        a_new = a - step
        if a_new <= 0:
            a_new = a / 2
        if abs(a_new - a) < 1e-12 * a:
            a = a_new
            break
        a = a_new
    return float(a), float(a / mean)


# the IW sums over j = 1..d below are written for d = 2, by the duplication formulas
# psi(z) + psi(z + 1/2) = 2 psi(2z) - 2 log 2 and psi_1(z) + psi_1(z + 1/2) = 4 psi_1(2z):
# sum_j psi((nu - j + 1) / 2) = 2 psi(nu - 1) - 2 log 2, and the same sum of psi_1 is
# 4 psi_1(nu - 1) (one evaluation each instead of two and a sum)
assert D == 2
_LOG4 = 2.0 * np.log(2.0)
SOLVE_RTOL = 1e-10        # relative tolerance of the Newton solves
GUESS_SHIFT = 0.75        # start of the nu solve: 3 / excess + this
GAMMA_C_MIN = 1e-12       # least log(mean) - E[log gamma] the Gamma shape solve takes
NU_BASE = IW_OFFSET - D - 1          # nu = d + 1 is v = 2d + 2
NU_MIN = NU_BASE + 1e-9


def solve_nu(target, lo, hi, start, iters=60):
    """
    Root of ``f(nu) = d log nu - sum_j digamma((nu - j + 1)/2) - target`` (decreasing)
    in ``[lo, hi]``, one per entry: the end of the bracket where the root lies outside it.

    Newton steps in ``u = 1 / nu``, kept inside a bracket that every evaluation of ``f``
    narrows (bisection where a step would leave it). Members with near-singular scale
    matrices (a wall seen as a line) can make ``f`` positive everywhere: unbounded, Newton
    ran to ``nu = 4e27``. Entries whose root lies outside the bracket take its end without
    iterating.

    Notes
    -----
    For large ``nu``, ``f(nu) ~ d log 2 + d (d + 1) / (2 nu) - target``: nearly linear in
    ``u``, so Newton in ``u`` converges in two or three steps where Newton in ``nu`` took
    up to twenty. The same expansion, shifted by 0.75 (exact to 1 % for ``d = 2`` and
    ``nu >= 3``), gives the first iterate; ``start`` serves where it is not positive.
    """
    hi = np.maximum(hi, lo)
    k = len(target)

    def f(nu, shift):
        # shift = 2 log 2 - t, taken once a solve
        x = nu - 1.0
        return 2.0 * (np.log(nu) - digamma(x)) + shift, x

    ends, _ = f(np.concatenate([lo, hi]), _LOG4 - np.concatenate([target, target]))
    below, above_hi = ends[:k] <= 0.0, ends[k:] >= 0.0
    out = np.where(below, lo, np.where(above_hi, hi, 0.0))
    free = ~(below | above_hi)
    if not free.any():
        return out
    t, a, b = target[free], lo[free], hi[free]
    shift = _LOG4 - t
    excess = t - _LOG4
    with np.errstate(divide='ignore', invalid='ignore'):
        guess = 3.0 / excess + GUESS_SHIFT
    nu = np.minimum(np.maximum(np.where(excess > 0.0, guess, start[free]), a), b)
    with np.errstate(divide='ignore', invalid='ignore'):        # fp = 0: bisection below
        for _ in range(iters):
            val, x = f(nu, shift)
            above = val > 0.0                             # the root is above nu
            a = np.where(above, nu, a)
            b = np.where(above, b, nu)
            fp = 2.0 / nu - 2.0 * _trigamma(x)
            nxt = nu / (1.0 + val / (nu * fp))                   # u - g(u) / g'(u)
            # inclusive: at the root (val == 0) the step stays on an end of the bracket,
            # and bisecting from there wanders off the root for a dozen steps
            inside = (nxt >= a) & (nxt <= b)
            if not inside.all():                        # bisect where it would leave
                nxt = np.where(inside, nxt, 0.5 * (a + b))
            done = (np.abs(nxt - nu) <= SOLVE_RTOL * nu).all()
            nu = nxt
            if done:
                break
    out[free] = nu
    return out


def _floor_extent(V, v):
    """
    ``V`` raised so that ``E[X] = V / (v - 2d - 2)`` has no semi-axis under
    ``MIN_SEMI_AXIS``.

    Notes
    -----
    Matching ``E[X^-1]`` averages inverse extents, so merging a line-like object (a wall
    segment seen for minutes) again and again drives its thin axis to zero: a MiR replay
    reached 8e-16 m^2, where ``log|V|`` loses all precision and the next merge's solve
    ran away. One centimetre is below the sensor noise, so the floor changes nothing
    measurable.
    """
    s = v - IW_OFFSET
    _, minor2 = eig2(V / s[:, None, None])
    lift = np.maximum(MIN_SEMI_AXIS ** 2 - minor2, 0.0)
    return V + (s * lift)[:, None, None] * np.eye(D)


def _nu_floor(mean_trace, t):
    """Smallest ``nu`` whose ``tr E[X] = nu t / (nu - d - 1)`` is within the ratio."""
    c = MEAN_EXTENT_RATIO * mean_trace
    return np.maximum(NU_BASE * c / np.maximum(c - t, 1e-300), NU_MIN)


def _iw_psi_sum(nu):
    """``sum_{j=1}^{d} digamma((nu - j + 1) / 2)`` for scalar or (k,) ``nu`` (d = 2)."""
    return 2.0 * digamma(np.asarray(nu, dtype=float) - 1.0) - _LOG4


def merge_iw(w, v, V):
    """
    Moment-matched inverse Wishart (Koch's ``v``, ``V``) of a weighted IW mixture.

    Notes
    -----
    With ``nu = v - d - 1``: ``E[X^-1] = nu V^-1`` and
    ``E[log|X|] = log|V| - d log 2 - sum_j digamma((nu - j + 1)/2)``. Matching both gives
    ``V = nu Psi^-1`` with ``Psi = sum w_i nu_i V_i^-1`` and
    ``f(nu) = d log nu - sum_j digamma((nu-j+1)/2) - (c + log|Psi| + d log 2) = 0``; ``f``
    decreases in ``nu``. Newton starts at the weighted mean of the ``nu_i`` (a few steps
    from the root) inside a bracket (:func:`solve_nu`): at most the largest ``nu_i`` (a
    merge is never more certain than its most certain member) and above ``d + 1`` so that
    ``v > 2d + 2``.

    Near that boundary ``E[X] = nu Psi^-1 / (nu - d - 1)`` diverges: members with very
    different extents can put the root there (a real replay merged a pedestrian into a
    2 km semi-axis). ``nu`` is therefore kept where ``tr E[X]`` is at most
    ``MEAN_EXTENT_RATIO`` times the trace of the mixture's mean extent, i.e.
    ``nu >= (d + 1) c T / (c T - t)`` with ``T = tr sum w_i E[X_i]``, ``t = tr Psi^-1``
    (``t <= T`` by Jensen). Ordinary merges stay well inside it and are exact matches.

    """
    wn = w / w.sum()
    nu_i = v - D - 1
    Psi = np.sum(wn[:, None, None] * nu_i[:, None, None] * inv2(V), axis=0)
    elog = float(np.sum(wn * (logdet_spd2(V) - _iw_psi_sum(nu_i))))
    target = elog + float(logdet_spd2(Psi))            # the d log 2 terms cancel
    mean_x = np.sum(wn[:, None, None] * V / (v - IW_OFFSET)[:, None, None], axis=0)
    lo = _nu_floor(np.trace(mean_x), np.trace(inv2(Psi)))
    nu = float(solve_nu(np.array([target]), np.array([lo]), np.array([np.max(nu_i)]),
                         np.array([np.sum(wn * nu_i)]))[0])
    V_new = _floor_extent(nu * inv2(Psi)[None], np.array([nu + D + 1]))[0]
    return float(nu + D + 1), symmetrize(V_new)


def merge_groups(mix: Mixture, groups: list) -> Mixture:
    """
    Merge each group of components (index arrays) into one, all groups in one batch.

    Weights add; the Gaussian is moment matched; the Gamma matches ``E[gamma]`` and
    ``E[log gamma]``; the inverse Wishart matches ``E[X^-1]`` and ``E[log|X|]`` (see
    :func:`merge_gamma` and :func:`merge_iw`, the same equations stated per group: they
    are the reference a test holds this batched solve to); the label is the heaviest
    member's. Newton runs vectorised over groups.

    """
    g = len(groups)
    sizes = np.fromiter(map(len, groups), dtype=np.int64, count=g)
    idx = np.concatenate(groups)
    starts = sizes.cumsum() - sizes
    gid = np.arange(g).repeat(sizes)
    w = mix.w[idx]
    W = np.add.reduceat(w, starts)
    wn = w / W[gid]
    m_i = mix.m[idx]
    m = np.add.reduceat(wn[:, None] * m_i, starts)
    dm = m_i - m[gid]
    spread = mix.P[idx] + dm[:, :, None] * dm[:, None, :]
    P = np.add.reduceat(wn[:, None, None] * spread, starts)
    # Gamma: log a - digamma(a) = log E[g] - E[log g] =: c
    al, be = mix.alpha[idx], mix.beta[idx]
    mean = np.add.reduceat(wn * al / be, starts)
    elog = np.add.reduceat(wn * (digamma(al) - np.log(be)), starts)
    c = np.maximum(np.log(mean) - elog, GAMMA_C_MIN)
    a = _gamma_shape_start(c)
    for _ in range(20):
        step = (np.log(a) - digamma(a) - c) / (1.0 / a - _trigamma(a))
        new = a - step
        positive = new > 0.0
        # halved where the step would leave a > 0 (rare: the where only then)
        a = new if positive.all() else np.where(positive, new, a * 0.5)
        if (np.abs(step) <= SOLVE_RTOL * a).all():
            break
    b = a / mean
    # inverse Wishart
    V_i = mix.V[idx]
    nu_i = mix.v[idx] - 3.0                # v - d - 1, exact: v > 6
    wnu = wn * nu_i
    Psi = np.add.reduceat(wnu[:, None, None] * inv2(V_i), starts)
    elog_x = np.add.reduceat(wn * (logdet_spd2(V_i) - _iw_psi_sum(nu_i)), starts)
    target = elog_x + logdet_spd2(Psi)
    mean_x = np.add.reduceat(wn[:, None, None] * mix.expected_extent(idx), starts)
    iPsi = inv2(Psi)
    lo = _nu_floor(mean_x[:, 0, 0] + mean_x[:, 1, 1], iPsi[:, 0, 0] + iPsi[:, 1, 1])
    nu = solve_nu(target, lo, np.maximum.reduceat(nu_i, starts),
                   np.add.reduceat(wnu, starts))
    V = _floor_extent(nu[:, None, None] * iPsi, nu + 2.0 + 1.0)
    # label of the heaviest member
    first = np.lexsort((-weight_key(w), gid))[starts]
    label = mix.label[idx[first]]
    return Mixture(W, a, b, m, symmetrize(P), nu + 2.0 + 1.0, symmetrize(V), label)


def merge_components(mix: Mixture, idx: np.ndarray):
    """Merge components ``idx`` into one: ``(w, alpha, beta, m, P, v, V, label)``."""
    out = merge_groups(mix, [np.asarray(idx)])
    return (out.w[0], out.alpha[0], out.beta[0], out.m[0], out.P[0], out.v[0], out.V[0],
            out.label[0])


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
    # a weight of 0 (or below the smallest normal double) is pruned even with
    # prune_weight 0: a group of such members has no weight to match moments by
    keep = mix.w >= max(prune_weight, _TINY)
    if not keep.all():
        mix = mix.take(keep)
    if not len(mix):
        return mix, 0
    kept, multi, absorbed, absorbed_w = _plan_merges(mix, merge_distance)
    # labels kept as their head: alone, or absorbing light members (after the others)
    rows = np.array(kept + absorbed, dtype=np.int64)
    w = mix.w[rows]
    if absorbed:
        w[len(kept):] = absorbed_w
    merged = Mixture(w, mix.alpha[rows], mix.beta[rows], mix.m[rows],
                     mix.P[rows], mix.v[rows], mix.V[rows], mix.label[rows])
    if multi:
        merged = Mixture.concat([merged, merge_groups(mix, multi)])
    capped = 0
    if len(merged) > max_components:
        order = (-weight_key(merged.w)).argsort(kind='stable')[:max_components]
        capped = len(merged) - max_components
        merged = merged.take(np.sort(order))
    return merged, capped


def _plan_merges(mix: Mixture, merge_distance: float):
    """
    ``(kept, multi, absorbed, absorbed_w)``: components kept as they are, groups to merge
    by moment matching, heads that absorb their light members' weight, and those weights.

    Common case in one pass: every component of a label lies within the merge distance of
    the label's heaviest component; only the other labels go through the greedy loop
    (:func:`_greedy_groups`).
    """
    members, member_w, far_group, heavy = _label_members(mix, merge_distance)
    kept, multi, absorbed, absorbed_w = [], [], [], []
    for g, group in enumerate(members):
        if far_group[g]:
            continue                                   # after the others, below
        if len(group) == 1:
            kept.append(group[0])
        elif heavy[g]:
            multi.append(np.array(group, dtype=np.int64))
        else:
            absorbed.append(group[0])
            ws = member_w[g]
            total = ws[0]
            for x in ws[1:]:                           # in order, as reduceat adds
                total += x
            absorbed_w.append(total)
    for g in (g for g, far in enumerate(far_group) if far):
        kept_g, multi_g = _greedy_groups(mix, np.array(members[g], dtype=np.int64),
                                         merge_distance)
        kept.extend(kept_g)
        multi.extend(multi_g)
    return kept, multi, absorbed, absorbed_w


def _label_members(mix: Mixture, merge_distance: float):
    """
    Per label: its members (heaviest first) and their weights, whether one lies beyond the
    merge distance of the head, and whether one has ``ABSORB_RATIO`` of the head's weight
    or more (lighter members move it by less than that: their weight is added to the head
    instead of a full moment match).
    """
    order, first, gid = mix.by_label()
    n_groups = int(gid[-1]) + 1
    heads = order[first]
    head = heads[gid]                                  # heaviest of each member's label
    pos = mix.m[:, :2]
    e = pos[order] - pos[head]
    d2 = np.einsum('ki,kij,kj->k', e, inv2(mix.P[heads][:, :2, :2])[gid], e)
    members = [[] for _ in range(n_groups)]
    member_w = [[] for _ in range(n_groups)]
    far_group = [False] * n_groups
    heavy = [False] * n_groups
    head_w = 0.0
    for g, o, far, w in zip(gid.tolist(), order.tolist(), (d2 > merge_distance).tolist(),
                            mix.w[order].tolist()):
        if not members[g]:
            head_w = w
        elif w >= ABSORB_RATIO * head_w:
            heavy[g] = True
        members[g].append(o)
        member_w[g].append(w)
        far_group[g] = far_group[g] or far
    return members, member_w, far_group, heavy


def _greedy_groups(mix: Mixture, remaining: np.ndarray, merge_distance: float):
    """
    Greedy merging of one label's members (heaviest first): the heaviest remaining
    absorbs those within ``merge_distance`` of its position. Returns the components kept
    alone and the groups to merge.
    """
    kept, multi = [], []
    while len(remaining):
        j = remaining[0]
        e = mix.m[remaining, :2] - mix.m[j, :2]
        d2 = np.einsum('ki,ij,kj->k', e, inv2(mix.P[j, :2, :2]), e)
        near = d2 <= merge_distance
        if near.sum() > 1:
            multi.append(remaining[near])
        else:
            kept.extend(remaining[near].tolist())
        remaining = remaining[~near]
    return kept, multi


def join_parts(mix: Mixture, heads: np.ndarray, weights: np.ndarray, label: int) -> Mixture:
    """
    One component for an object tracked as separate parts (a walker's two legs).

    ``heads`` are the parts' components, ``weights`` their labels' total weights. Each
    part counts by its expected returns (weight times rate). The kinematics are moment
    matched; the extent is the second moment of the union, each part's expected extent
    about the joint centre, kept at the parts' least certain ``v``; the rate is the sum of
    the parts' rates, at their least certain ``beta``. The weight is the heaviest part's:
    the parts are one object. The result carries ``label``.
    """
    heads = np.asarray(heads)
    rate = mix.alpha[heads] / mix.beta[heads]
    share = weights * rate
    share = share / share.sum()
    m = share @ mix.m[heads]
    dm = mix.m[heads] - m
    P = np.einsum('k,kij->ij', share, mix.P[heads] + dm[:, :, None] * dm[:, None, :])
    dc = dm[:, :2]
    X = np.einsum('k,kij->ij', share, mix.expected_extent(heads) + dc[:, :, None] * dc[:, None, :])
    v = float(mix.v[heads].min())
    beta = float(mix.beta[heads].min())
    return Mixture(np.array([float(np.max(weights))]), np.array([rate.sum() * beta]),
                   np.array([beta]), m[None], symmetrize(P)[None], np.array([v]),
                   symmetrize(X * (v - IW_OFFSET))[None], np.array([label], dtype=np.int64))
