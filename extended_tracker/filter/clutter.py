"""
The clutter rate the filter learns from the scans.

``model.clutter_rate`` is what the user tells the filter; a laser in rain, dust or
glass may return far more spurious points than that. After each update the filter
counts the detections its posterior takes as clutter and keeps their exponential
average over ``model.clutter_memory`` seconds (``FilterState.clutter_rate``). The next
update assumes the larger of the two: the told rate is a floor, so a clean scene
behaves as it is told.
"""

from __future__ import annotations

import numpy as np

from ..config import TrackerConfig
from .cphd import UpdateWeights
from .state import FilterState


def clutter_rate_in_use(state: FilterState, cfg: TrackerConfig) -> float:
    """The clutter rate the update assumes: ``model.clutter_rate``, or what the scans
    taught the filter where that is more."""
    return max(cfg.model.clutter_rate, state.clutter_rate or 0.0)


def clutter_count(weights: UpdateWeights, cell_size: np.ndarray, n_points: int) -> float:
    """
    The scan's detections the posterior takes as clutter: every detection, less each
    cell's detections times the expected number of objects (births included) that made
    it, summed over the partitions that hold the cell, weighted by theirs. Each partition
    covers every detection once, so the objects' share cannot exceed the detections.
    """
    made = np.clip(np.exp(weights.log_w_detected).sum(axis=0), 0.0, 1.0)
    return max(0.0, n_points - float(np.dot(cell_size, made)))


def learned_clutter_rate(learned: float | None, count: float, dt: float,
                         cfg: TrackerConfig) -> float | None:
    """
    The clutter rate after one more scan's ``count``: an exponential average over
    ``model.clutter_memory`` seconds (the first scan's count as it is; None with the
    memory 0, learning off).
    """
    memory = cfg.model.clutter_memory
    if memory <= 0.0:
        return None
    if learned is None:
        return count
    return float(learned + (1.0 - np.exp(-dt / memory)) * (count - learned))
