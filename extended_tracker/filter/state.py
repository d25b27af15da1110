"""
The filter's state, carried from scan to scan: the labelled GGIW mixture and the
cardinality pmf, and the clutter rate learned from the scans. The prediction of the
first two.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import TrackerConfig
from .births import birth_intensity, region_births
from .cardinality import predict_cardinality, resize_cardinality
from .ggiw import predict
from .mixture import Mixture


@dataclass(frozen=True)
class FilterState:
    """
    The posterior of the filter.

    Attributes
    ----------
    mixture : Mixture
        Posterior GGIW mixture; each component carries a track label.
    log_card : (N_max + 1,) array
        Posterior cardinality pmf (log).
    next_label : int
        Next unused track label.
    clutter_rate : float or None
        Mean clutter detections per scan learned from the scans so far
        (:mod:`.clutter`); None before the first.

    """

    mixture: Mixture
    log_card: np.ndarray
    next_label: int = 1
    clutter_rate: float | None = None

    @staticmethod
    def initial(cfg: TrackerConfig, next_label: int = 1) -> 'FilterState':
        """An empty scene: no components, cardinality certainly zero."""
        log_card = np.full(cfg.model.n_max + 1, -np.inf)
        log_card[0] = 0.0
        return FilterState(Mixture.empty(), log_card, next_label)


def predict_state(state: FilterState, dt: float, cfg: TrackerConfig) -> FilterState:
    """
    Predict the mixture and cardinality ``dt`` seconds ahead; add region births.

    The cardinality prediction includes the Poisson birth of the region components and of
    the uniform birth intensity that the update evaluates per cell.
    """
    mc = cfg.model
    mixture = predict(state.mixture, dt, mc.p_survival, mc.sigma_accel, mc.tau_rate,
                      mc.tau_extent)
    next_label = state.next_label
    birth_mean = birth_intensity(cfg, dt)
    if len(cfg.birth.regions):
        regions = region_births(cfg, next_label)
        next_label += len(regions)
        birth_mean += float(np.sum(regions.w))
        mixture = Mixture.concat([mixture, regions])
    log_card = state.log_card
    if len(log_card) != mc.n_max + 1:                 # N_max changed while running
        log_card = resize_cardinality(log_card, mc.n_max)
    log_card = predict_cardinality(log_card, mc.p_survival ** dt, birth_mean)
    return FilterState(mixture, log_card, next_label, state.clutter_rate)
