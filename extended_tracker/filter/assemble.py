"""
The posterior mixture of one update: missed components, updated pairs and births, with
their labels, and what each label's update says for extraction.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..config import TrackerConfig
from ..diagnostics import Diagnostics
from .algebra2 import eig2
from .births import birth_label_cells, cell_claims, label_births
from .cphd import UpdateWeights
from .mixture import Mixture, weight_key
from .state import FilterState


@dataclass(frozen=True)
class UpdateFacts:
    """
    Per label, what the update says (for extraction).

    Attributes
    ----------
    detections : dict
        Label -> size of its heaviest detected cell, where detection outweighs a miss (a
        new label: its heaviest birth cell).
    visibility : dict
        Label -> visible fraction of its heaviest predicted component.
    widths : dict
        Label -> width of the returns of that same cell (m, :func:`cell_widths`).

    """

    detections: dict = field(default_factory=dict)
    visibility: dict = field(default_factory=dict)
    widths: dict = field(default_factory=dict)


def assemble(pred: FilterState, pairs, kept, weights: UpdateWeights, visibility,
             cfg: TrackerConfig, diag: Diagnostics):
    """
    The posterior mixture before reduction, the next free label and the label facts.

    Detected pairs lighter than ``reduction.prune_weight`` and births lighter than
    ``birth.min_weight`` are left out. Births take labels by :func:`births.label_births`.

    Returns
    -------
    posterior : Mixture
    next_label : int
    facts : UpdateFacts

    """
    mix, n_comp = pred.mixture, len(pred.mixture)
    w_missed = np.exp(weights.log_w_missed[:n_comp])
    w_det = np.exp(weights.log_w_detected[kept.comp, kept.cell])
    sel = (w_det >= cfg.reduction.prune_weight).nonzero()[0]
    w_birth = np.exp(weights.log_w_detected[n_comp, :])
    bsel = (w_birth >= cfg.birth.min_weight).nonzero()[0]
    # which label explains each cell best is asked only where a birth may take it
    claims = (cell_claims(mix, kept.comp, kept.cell, w_det, pairs.n_cells) if len(bsel)
              else (None, None))
    born, next_label = label_births(pairs.partitions, bsel, pred.next_label, *claims, w_birth)
    diag.births = len(set(born.tolist()))
    # the detected pairs kept, then the births: one gather from the batched update
    rows = np.concatenate([kept.rows[sel], len(pairs.comp) + bsel])
    posterior = Mixture.concat([
        mix.with_weights(w_missed),
        pairs.updated.take(rows).mixture(np.concatenate([w_det[sel], w_birth[bsel]]),
                                         np.concatenate([mix.label[kept.comp[sel]], born]))])
    cells = detected_cells(mix, kept.comp, kept.cell, w_det, w_missed)
    cells.update(birth_label_cells(born, bsel, w_birth, pred.next_label))
    width = cell_widths(pairs.stats)
    return posterior, next_label, UpdateFacts(
        {lab: int(pairs.stats.n[c]) for lab, c in cells.items()},
        _visibility_per_label(mix, visibility),
        {lab: float(width[c]) for lab, c in cells.items()})


def cell_widths(stats) -> np.ndarray:
    """
    Per cell, the width of its returns (m): ``sqrt(12 l (n - 1) / (n + 1))``, ``l`` the
    largest eigenvalue of the scatter of its ``n`` returns over ``n``: the length of the
    segment its returns would lie evenly spaced along, end to end (0 for a lone return).
    """
    n = np.maximum(stats.n, 1).astype(float)
    spread = eig2(stats.scatter / n[:, None, None])[0]
    return np.sqrt(12.0 * np.maximum(spread, 0.0) * (n - 1.0) / (n + 1.0))


def _visibility_per_label(mix: Mixture, visibility) -> dict:
    """Each label's visible fraction: its heaviest predicted component's."""
    if visibility is None or not len(mix):
        return {}
    order, is_head, _ = mix.by_label()
    heads = order[is_head]
    return dict(zip(mix.label[heads].tolist(), visibility[heads].tolist()))


def detected_cells(mix: Mixture, comp, cell, w_det, w_missed) -> dict:
    """
    Each label's heaviest detected cell, where the label's detected weight outweighs its
    missed weight. Ties in weight but for the last bits: the first pair
    (:func:`mixture.weight_key`).
    """
    if not len(comp):
        return {}
    labels, rank, _ = mix.per_label()
    missed = np.bincount(rank, weights=w_missed, minlength=len(labels))
    detected = np.bincount(rank[comp], weights=w_det, minlength=len(labels))
    keys = weight_key(w_det)
    heaviest = {}                                      # label rank -> its heaviest pair
    for j, r in enumerate(rank[comp].tolist()):
        if r not in heaviest or keys[j] > keys[heaviest[r]]:
            heaviest[r] = j
    return {int(labels[r]): int(cell[j]) for r, j in sorted(heaviest.items())
            if detected[r] > missed[r]}
