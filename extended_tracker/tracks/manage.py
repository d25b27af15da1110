"""
Track management: from the filter's reduced posterior to the objects a user sees.

:func:`manage_tracks` runs once per scan on the posterior of the filter update. Labels
that track one object are fused, and a label whose components ended far apart is split
(:mod:`tracks.labels`); the heaviest labels are extracted (:mod:`tracks.extract`); the
ids are kept meaningful (:mod:`tracks.identity`: jumps, hand-over, the report record);
leg pairs become one track (:mod:`tracks.pairs`); confirmed labels are shown, the thin
pieces of one contour as one object (:mod:`tracks.grouping`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..config import TrackerConfig
from ..diagnostics import Diagnostics
from ..filter.assemble import UpdateFacts
from ..filter.state import FilterState
from .estimates import Estimates
from .extract import extract
from .grouping import group_segments
from .identity import hand_over, record_reports, relabel_jumps, remember_shown
from .labels import fuse_duplicate_labels, split_labels
from .pairs import join_pairs
from .record import find_sorted, NO_LABELS, TrackRecord


def manage_tracks(filt: FilterState, record: TrackRecord, facts: UpdateFacts,
                  cfg: TrackerConfig, dt: float, first_label: int,
                  diag: Diagnostics) -> tuple[FilterState, TrackRecord, Estimates]:
    """
    Fuse and split labels, extract, keep the ids and the record; report the confirmed.

    Parameters
    ----------
    filt : FilterState
        The reduced posterior of the update.
    record : TrackRecord
        The record as the previous scan left it.
    facts : UpdateFacts
        The update's detections and visibility per label.
    dt : float
        Seconds since the previous scan.
    first_label : int
        The label counter at the start of this scan (after the prediction).
    diag : Diagnostics
        Filled with the counts of this stage.

    Returns
    -------
    filt : FilterState
        The posterior with its labels as reported.
    record : TrackRecord
    shown : Estimates
        The confirmed labels, the thin pieces of one contour reported as one object.

    """
    filt = relabel_parts(filt, record, cfg, diag)
    candidates = extract(filt, cfg, facts.detections, facts.visibility)
    filt, candidates, diag.relabelled = relabel_jumps(record, filt, candidates, cfg, dt)
    filt, candidates, renamed, diag.handed_over = hand_over(record, filt, candidates, cfg, dt,
                                                            first_label)
    new_record = record_reports(renamed, candidates)
    joined = forming = NO_LABELS
    if cfg.reduction.pair_scans:
        filt, new_record, candidates, joined, forming = join_pairs(filt, new_record,
                                                                   candidates, cfg, facts.widths)
        diag.joined_labels = len(joined)
    confirmed = _to_show(new_record, record, candidates, forming, cfg)
    shown = candidates.take(confirmed)
    new_record = remember_shown(new_record, filt, shown, dt, first_label,
                                cfg.extraction.handover_time, joined)
    # the record keeps the filter's own estimates; the report groups contour pieces
    shown, diag.grouped = group_segments(shown, new_record.reported_scans[confirmed],
                                         cfg.extraction.group_gap, cfg.extraction.group_speed)
    return filt, new_record, shown


def relabel_parts(filt: FilterState, record: TrackRecord, cfg: TrackerConfig,
                  diag: Diagnostics) -> FilterState:
    """Fuse labels that track one object; split labels whose components are far apart."""
    rc = cfg.reduction
    mix, diag.fused_labels = fuse_duplicate_labels(
        filt.mixture, rc.merge_distance, rc.fuse_weight, record.reported,
        record.reported_scans)
    mix, next_label = split_labels(mix, rc.split_weight, rc.merge_distance, filt.next_label)
    diag.components = len(mix)
    return replace(filt, mixture=mix, next_label=next_label)


def _to_show(new_record: TrackRecord, record: TrackRecord, candidates: Estimates,
             forming: np.ndarray, cfg: TrackerConfig) -> np.ndarray:
    """
    Which candidates are shown: confirmed (M of N), and not a part never shown that waits
    while its pair forms.
    """
    confirmed = new_record.confirmed_rows(cfg.extraction)
    if len(forming):
        confirmed &= ~(find_sorted(np.sort(forming), candidates.label)[1]
                       & ~find_sorted(record.shown, candidates.label)[1])
    return confirmed
