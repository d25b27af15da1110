"""
Births: the uniform birth intensity evaluated per cell, configured birth regions, and
the labels new components take.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..config import TrackerConfig
from .distance import find_root, union_min
from .mixture import group_heads, IW_OFFSET, Mixture, weight_key
from .tables import cached_tables


def region_births(cfg: TrackerConfig, first_label: int) -> Mixture:
    """Birth components of the configured birth regions (x, y, std triples)."""
    if not len(cfg.birth.regions):
        return Mixture.empty()                  # the default: no array work on each scan
    reg = np.asarray(cfg.birth.regions, dtype=float).reshape(-1, 3)
    k = len(reg)
    b = cfg.birth
    P = np.zeros((k, 4, 4))
    P[:, 0, 0] = P[:, 1, 1] = reg[:, 2] ** 2
    P[:, 2, 2] = P[:, 3, 3] = b.velocity_std ** 2
    m = np.zeros((k, 4))
    m[:, :2] = reg[:, :2]
    X0 = (b.extent_semi_axis ** 2) * np.eye(2)
    v = np.full(k, float(b.dof))
    V = np.broadcast_to((b.dof - IW_OFFSET) * X0, (k, 2, 2)).copy()
    alpha = np.full(k, float(b.rate_shape))
    return Mixture(np.full(k, float(b.weight)), alpha, alpha / b.expected_rate, m, P, v, V,
                   np.arange(first_label, first_label + k, dtype=np.int64))


def birth_intensity(cfg: TrackerConfig, dt: float) -> float:
    """Expected number of objects appearing anywhere in ``dt`` seconds."""
    return cfg.birth.rate * max(dt, 1e-3)


def birth_prior(stats, cfg: TrackerConfig, area: float) -> Mixture:
    """
    One GGIW per cell standing for the uniform birth intensity at that cell.

    Notes
    -----
    The birth intensity is uniform in position over the clutter area ``A``. For a cell
    ``W`` its position integral is evaluated with a component centred at the cell mean whose
    position covariance ``s^2 I`` has the uniform's density at its centre,
    ``1 / (2 pi s^2) = 1 / A``; everything else (velocity, rate, extent) is the birth prior.
    The extent prior mean is the floor semi-axis circle; its few degrees of freedom let the
    cell's own scatter decide (same ``rho`` as the update: trap 2).
    """
    b = cfg.birth
    k = len(stats.n)
    P0, V0 = _birth_row(area, b.velocity_std, b.extent_semi_axis, b.dof)
    m = np.zeros((k, 4))
    m[:, :2] = stats.mean
    # beta as rate_shape / expected_rate once, in Python: the same double as dividing
    # every alpha by expected_rate
    alpha, beta = np.full(k, float(b.rate_shape)), np.full(k, b.rate_shape / b.expected_rate)
    return Mixture(np.full(k, 1.0), alpha, beta, m, P0.repeat(k, axis=0), np.full(k, float(b.dof)),
                   V0.repeat(k, axis=0), np.zeros(k, dtype=np.int64))


@cached_tables(maxsize=16)             # constant while the field of view and config are
def _birth_row(area: float, velocity_std: float, extent_semi_axis: float, dof: float):
    """Position-velocity covariance (1, 4, 4) and IW scale (1, 2, 2) of a birth row."""
    P = np.zeros((1, 4, 4))
    P[:, 0, 0] = P[:, 1, 1] = area / (2.0 * np.pi)
    P[:, 2, 2] = P[:, 3, 3] = velocity_std ** 2
    X0 = (extent_semi_axis ** 2) * np.eye(2)
    return P, ((dof - IW_OFFSET) * X0)[None]


def birth_log_miss_factor(cfg: TrackerConfig) -> float:
    """``log q_D`` of the birth intensity: ``1 - p_D0 (1 - (beta/(beta+1))^alpha)``."""
    return _birth_log_miss(cfg.birth.rate_shape, cfg.birth.expected_rate, cfg.detection.p_d0)


@lru_cache(maxsize=64)                 # constant while the configuration is
def _birth_log_miss(alpha: float, expected_rate: float, p_d0: float) -> float:
    beta = alpha / expected_rate
    log_e0 = alpha * (np.log(beta) - np.log1p(beta))
    return float(np.log1p(p_d0 * np.expm1(log_e0)))


def cell_claims(mix: Mixture, comp, cell, w_det, n_cells):
    """
    The label with the most detected weight on each cell, and that weight (0 if none),
    from the (component, cell) pairs.
    """
    claim = np.zeros(n_cells, dtype=np.int64)
    weight = np.zeros(n_cells)
    if not len(cell):
        return claim, weight
    labels, rank, _ = mix.per_label()
    per = np.zeros((len(labels), n_cells))
    np.add.at(per, (rank[comp], cell), w_det)
    best = weight_key(per).argmax(axis=0)             # ties: the first label
    return labels[best], per[best, np.arange(n_cells)]


def label_births(pset, birth_label_cells, next_label, claim=None, claim_weight=None,
                  birth_weight=None):
    """
    Labels of new components: cells that share detections get one label.

    Overlapping cells (a cell and its sub-cells from other partitions) are alternative
    explanations of the same returns, so their birth hypotheses are one new object and
    merge; cells with no detection in common are different objects.

    A birth on a cell that an existing label explains with more weight than the birth is
    an alternative hypothesis of that object (a restart at zero velocity), not a new
    object: it takes that label. Otherwise a second label would follow the object and
    take it over whenever its fresh extent fits a scan better, a new id each time.
    """
    k = len(birth_label_cells)
    if not k:
        return np.zeros(0, dtype=np.int64), next_label
    out = np.zeros(k, dtype=np.int64)
    if claim is not None:
        claimed = claim_weight[birth_label_cells] > birth_weight[birth_label_cells]
        out[claimed] = claim[birth_label_cells[claimed]]
        free = (~claimed).nonzero()[0]
        if len(free) < k:
            out[free], next_label = label_births(pset, birth_label_cells[free], next_label)
            return out, next_label
    parent = list(range(k))
    owner = {}
    for i, c in enumerate(birth_label_cells):
        for z in pset.cells[c].tolist():
            j = owner.setdefault(z, i)
            if j != i:
                union_min(parent, i, j)
    roots = np.array([find_root(parent, i) for i in range(k)])
    uniq, inverse = np.unique(roots, return_inverse=True)
    return (next_label + inverse).astype(np.int64), next_label + len(uniq)


def birth_label_cells(born, bsel, w_birth, first_new: int):
    """``(label, cell)`` of each new label (``>= first_new``) and its heaviest birth cell
    (``born`` labels the birth cells ``bsel``; ``w_birth`` the weights of all cells;
    weights that tie but for their last bits order by row, :func:`weight_key`)."""
    new = (born >= first_new).nonzero()[0]
    if not len(new):
        return []
    order, is_head = group_heads(born[new], -weight_key(w_birth[bsel[new]]))
    head = new[order[is_head]]
    return list(zip(born[head].tolist(), bsel[head].tolist()))
