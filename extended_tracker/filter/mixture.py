"""
The labelled GGIW mixture: a struct of arrays with a leading component axis
(``doc/model.md``, section 1).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .tables import read_only

D = 2                     # extent dimension


IW_OFFSET = 2 * D + 2     # E[X] = V / (v - IW_OFFSET); v must exceed it


@dataclass(frozen=True)
class Mixture:
    """
    A GGIW mixture with a leading component axis of length ``n``.

    Attributes
    ----------
    w : (n,) array
        Weights (expected number of objects each component stands for).
    alpha, beta : (n,) arrays
        Gamma shape and rate of the measurement rate; ``E[gamma] = alpha / beta``.
    m : (n, 4) array
        Kinematic mean ``[px, py, vx, vy]`` (m, m/s).
    P : (n, 4, 4) array
        Kinematic covariance.
    v : (n,) array
        Inverse Wishart degrees of freedom, ``v > 6``.
    V : (n, 2, 2) array
        Inverse Wishart scale (m^2).
    label : (n,) int64 array
        Track label carried from birth through updates.

    """

    w: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    m: np.ndarray
    P: np.ndarray
    v: np.ndarray
    V: np.ndarray
    label: np.ndarray

    def __len__(self) -> int:
        return len(self.w)

    def take(self, idx) -> 'Mixture':
        """Return the components at ``idx`` (index array or boolean mask)."""
        return Mixture(self.w[idx], self.alpha[idx], self.beta[idx], self.m[idx],
                       self.P[idx], self.v[idx], self.V[idx], self.label[idx])

    def with_weights(self, w) -> 'Mixture':
        """Return a copy with new weights."""
        return Mixture(np.asarray(w, dtype=float), self.alpha, self.beta, self.m, self.P,
                       self.v, self.V, self.label)

    @staticmethod
    def empty() -> 'Mixture':
        """Return a mixture with no components."""
        return Mixture(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros((0, 4)),
                       np.zeros((0, 4, 4)), np.zeros(0), np.zeros((0, D, D)),
                       np.zeros(0, dtype=np.int64))

    @staticmethod
    def concat(parts) -> 'Mixture':
        """Concatenate mixtures along the component axis."""
        parts = [p for p in parts if len(p)]
        if not parts:
            return Mixture.empty()
        if len(parts) == 1:
            return parts[0]
        cat = np.concatenate
        return Mixture(cat([p.w for p in parts]), cat([p.alpha for p in parts]),
                       cat([p.beta for p in parts]), cat([p.m for p in parts]),
                       cat([p.P for p in parts]), cat([p.v for p in parts]),
                       cat([p.V for p in parts]), cat([p.label for p in parts]))

    def expected_extent(self, idx=None) -> np.ndarray:
        """Return ``E[X] = V / (v - 6)``, shape (n, 2, 2), or of the components ``idx``."""
        return self._extent if idx is None else self._extent[idx]

    @cached_property
    def _extent(self):
        # gating, the p_D model and the plausibility check all ask for it: computed once,
        # shared, so read-only
        return read_only(self.V / (self.v - IW_OFFSET)[:, None, None])[0]

    def expected_rate(self) -> np.ndarray:
        """Return ``E[gamma] = alpha / beta``, shape (n,)."""
        return self.alpha / self.beta

    def by_label(self):
        """
        Components grouped by label, each label's heaviest first.

        Returns
        -------
        order : (n,) int array
            Component indices, labels ascending, weights descending within a label (ties,
            to float32's precision, by index: :func:`weight_key`).
        is_head : (n,) bool array
            Over ``order``: the first (heaviest) component of its label.
        group : (n,) int array
            Over ``order``: the label's rank among the labels.

        Computed once per mixture; the arrays are shared, so they are read-only.
        A step asks for it up to five times, often of the same mixture when fusion and
        splitting change nothing.
        """
        return self._by_label

    def per_label(self):
        """
        ``(labels, rank, weight)``: the labels ascending, each component's index into
        them, and each label's total weight (summed in component order). Computed once
        per mixture, like :meth:`by_label`.
        """
        return self._per_label

    @cached_property
    def _per_label(self):
        order, is_head, group = self.by_label()
        rank = np.empty(len(order), dtype=np.int64)
        rank[order] = group
        return read_only(self.label[order[is_head]], rank, np.bincount(rank, weights=self.w))

    @cached_property
    def _by_label(self):
        order = self.label.argsort(kind='stable')
        lab = self.label[order]
        if (lab[1:] != lab[:-1]).all():
            # one component a label (a predicted or reduced mixture, most scans): each is
            # its label's head, and the weights order nothing
            n = len(order)
            return read_only(order, np.ones(n, dtype=bool), np.arange(n))
        order, is_head = group_heads(self.label, -weight_key(self.w))
        return read_only(order, is_head, is_head.cumsum() - 1)


def group_heads(group: np.ndarray, key: np.ndarray):
    """
    ``(order, is_head)``: indices sorted by ``group`` ascending, then by ``key`` ascending
    (ties by index), and over that order whether each is the first of its group (with
    ``key = -weight_key(w)``, its heaviest).
    """
    order = np.lexsort((key, group))
    g = group[order]
    is_head = np.empty(len(order), dtype=bool)
    is_head[:1] = True
    np.not_equal(g[1:], g[:-1], out=is_head[1:])
    return order, is_head


def weight_key(w) -> np.ndarray:
    """
    Weights as keys for ordering: rounded to float32, so that weights equal but for their
    last bits tie, and the stable sorts order them by index, on every CPU.

    Such ties are structural: the CPHD update gives each cell that one component alone
    explains the weight of its partition, every cell through roundings of its own, and
    numpy's float64 ``exp`` and ``log`` differ in the last bit between CPUs. Which of two
    tied components heads a label (is reported, absorbs the other, keeps the label) must
    not rest on those bits.
    """
    return np.asarray(w, dtype=np.float32)
