"""
The tracker on detections alone: filter update and track management without a scan.

:func:`filter_step` predicts, updates and manages the tracks of one set of Cartesian
detections with a constant (or given) p_D. The per-scan pipeline
(:mod:`extended_tracker.pipeline`) runs the same stages with the scan's own detection
model in between; this is the form for synthetic tests, benchmarks and oracles.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .config import TrackerConfig
from .diagnostics import Diagnostics
from .filter.state import FilterState, predict_state
from .filter.update import pair_updates, SensorTerms, update
from .tracks.estimates import Estimates
from .tracks.manage import manage_tracks
from .tracks.record import TrackRecord


@dataclass(frozen=True)
class TrackerState:
    """The filter's posterior and the record of the ids shown."""

    filter: FilterState
    tracks: TrackRecord = field(default_factory=TrackRecord)

    @staticmethod
    def initial(cfg: TrackerConfig) -> 'TrackerState':
        """No objects, no record."""
        return TrackerState(FilterState.initial(cfg))


def filter_step(state: TrackerState, points: np.ndarray, dt: float, cfg: TrackerConfig,
                p_d=None, clutter_area: float | None = None
                ) -> tuple[TrackerState, Estimates, Diagnostics]:
    """
    Predict, update, reduce and manage the tracks of one set of detections.

    ``p_d`` may be a number, or a callable taking the predicted mixture and returning
    per-component probabilities; by default ``detection.p_d0`` for every component.
    ``clutter_area`` (m^2) is where births and clutter are spread
    (``model.surveillance_area`` by default).

    Returns the new state, the objects shown and the step's counts.
    """
    pred = predict_state(state.filter, dt, cfg)
    n = len(pred.mixture)
    if callable(p_d):
        sensor = SensorTerms(np.asarray(p_d(pred.mixture), dtype=float))
    else:
        sensor = SensorTerms.constant(n, cfg.detection.p_d0 if p_d is None else p_d)
    return update_step(state, pred, points, sensor, cfg, dt, clutter_area)


def update_step(state: TrackerState, pred: FilterState, points: np.ndarray,
                sensor: SensorTerms, cfg: TrackerConfig, dt: float,
                clutter_area: float | None = None,
                clutter_log_density: np.ndarray | None = None
                ) -> tuple[TrackerState, Estimates, Diagnostics]:
    """
    Update the prediction ``pred`` of ``state.filter`` with the detections ``points`` and
    manage the tracks. The pairs take their component's p_D (no scan to evaluate it
    where the cell puts the object).
    """
    diag = Diagnostics(detections=len(np.asarray(points).reshape(-1, 2)))
    pairs = pair_updates(pred.mixture, points, cfg, sensor, clutter_area, clutter_log_density)
    filt, facts = update(pred, pairs, sensor, np.asarray(sensor.p_d)[pairs.comp], cfg, dt,
                         diag, confirmed=state.tracks.confirmed_labels(cfg.extraction))
    filt, tracks, shown = manage_tracks(filt, state.tracks, facts, cfg, dt, pred.next_label,
                                        diag)
    return TrackerState(filt, tracks), shown, diag
