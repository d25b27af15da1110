"""
The stages of one scan that join sensing, the filter and the tracks, in the order
:func:`pipeline.step` calls them: the static background removed, the tracks that stood on
it dropped, the detection model of the prediction, the filter update with the scan's
sensor model, then track management.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from .config import TrackerConfig
from .diagnostics import Diagnostics
from .filter.algebra2 import inv2
from .filter.cardinality import thin_cardinality
from .filter.ggiw import gate_covariance, gate_distance2
from .filter.state import FilterState
from .filter.update import gate_threshold, pair_updates, sensor_noise, SensorTerms, update
from .frames.pose import kinematics_to_inner, mixture_to_inner, Pose2
from .sensing.background import arrived, BackgroundState, beams_near_tracks, update_background
from .sensing.detection import (
    detection_model, pair_detection_probability, sparse_births, Visibility,
)
from .sensing.objects import object_beams
from .sensing.scan import ScanPoints
from .sensing.static_map import StaticMap, update_static_map
from .tracks.manage import manage_tracks
from .tracks.record import find_sorted, TrackRecord

if TYPE_CHECKING:                                   # the pipeline imports these stages
    from .pipeline import PipelineState


@dataclass(frozen=True)
class Foreground:
    """
    What :func:`remove_background` leaves: the learned per-beam ``background`` and
    ``static_map``, the foreground ``points`` and the ``background_points`` (fixed frame),
    the returns ``learned`` as static this scan, the labels seen to move, and which
    ``beams`` the foreground returns lie on (None with the background off).
    """

    background: BackgroundState | None
    static_map: StaticMap | None
    points: np.ndarray
    background_points: np.ndarray
    learned: np.ndarray
    moved: np.ndarray
    beams: np.ndarray | None = None


def remove_background(state: PipelineState, tracks: TrackRecord, sp: ScanPoints, dt: float,
                      cfg: TrackerConfig, diag: Diagnostics, pose: Pose2 | None = None,
                      own_dt: float | None = None) -> Foreground:
    """
    Drop static returns; never learn those of tracks that have moved.

    Confirmed, person-sized tracks that have moved protect their returns; a label seen to
    move keeps protecting while it lives, though its report record (and travel) restarts
    after a scan it was not reported in. During the warm-up the background is learned
    and only objects (:mod:`sensing.objects`) and, while the scanner stands, what came
    into a beam reach the filter, so walls are never tracked.

    With the scanner's ``pose`` in a fixed frame, once the scanner has moved, the static
    map learned there (:mod:`sensing.static_map`), seeded with what the per-beam
    background knew, drops returns too, with the per-beam background (learned anew
    wherever the scanner stops). A scanner that never moves costs nothing more. The
    points come back in the fixed frame.
    """
    empty = np.zeros((0, 2))
    view = pose or Pose2()
    if not cfg.background.enabled or not len(sp.angles):
        return Foreground(state.background, state.static_map, view.to_outer(sp.points), empty,
                          empty, state.moved)
    est, bgc = state.last_estimates, cfg.background
    travel = tracks.confirmed_travel(est.label, cfg.extraction)
    moved = np.union1d(state.moved[find_sorted(tracks.shown, state.moved)[1]],
                       est.label[travel >= bgc.moved_distance])
    major = est.axes()[0] if len(est) else np.zeros(0)
    guard = find_sorted(moved, est.label)[1] & (major <= bgc.protect_semi_axis)
    protect, near = beams_near_tracks(sp, view.to_inner(est.m[:, :2]), major, bgc.track_gate,
                                      guard)
    objects, small = object_beams(sp, bgc.object_size, bgc.margin, cfg.birth.min_points)
    # the per-beam background ages by its own scanner's period (several scanners take
    # turns: the time since the last scan is another's)
    background, keep = update_background(state.background, sp, dt if own_dt is None else own_dt,
                                         bgc, protect, near, objects)
    learned = background.learned[sp.beam]
    static_map = state.static_map
    if pose is not None and state.moving:
        if static_map is None:    # it starts to move: seeded with what the background knew
            static_map = StaticMap.seeded(pose, sp, ~keep, bgc)
        static_map, on_map, map_learned = update_static_map(static_map, sp, pose, dt, bgc,
                                                            protect | objects)
        keep &= ~on_map
        learned |= map_learned
    diag.background_dropped = len(keep) - int(np.count_nonzero(keep))
    if state.elapsed + dt <= bgc.warmup:      # walls are learned; what is small or came is
        diag.warmup = 1                       # tracked
        # standing still, the scanner sees what came into a beam (a car driving in)
        came = arrived(state.background, sp, bgc.margin) & (not state.moving)
        keep &= (small | came)[sp.beam]
    points, bg_points = view.to_outer(sp.points[keep]), view.to_outer(sp.points[~keep])
    beams = np.zeros(len(sp.angles), dtype=bool)
    beams[sp.beam[keep]] = True
    return Foreground(background, static_map, points, bg_points,
                      view.to_outer(sp.points[learned]), moved, beams)


def drop_absorbed(pred: FilterState, learned: np.ndarray, points: np.ndarray,
                  cfg: TrackerConfig, diag: Diagnostics, first_new: int) -> FilterState:
    """
    Drop the tracks that stood on returns just learned as background with no foreground
    return left (not the region births of this scan, labels from ``first_new`` on), and
    take their weight from the cardinality: they are not left to coast onto a
    neighbour's returns.
    """
    mix = pred.mixture
    if not len(learned) or not len(mix) or diag.warmup:
        return pred
    on_bg = absorbed(mix, learned, points, cfg) & (mix.label < first_new)
    if not on_bg.any():
        return pred
    diag.absorbed = int(np.count_nonzero(on_bg))
    return replace(pred, mixture=mix.take(~on_bg),
                   log_card=thin_cardinality(pred.log_card, float(mix.w[on_bg].sum())))


def absorbed(mix, learned: np.ndarray, points: np.ndarray, cfg: TrackerConfig) -> np.ndarray:
    """
    The components that gate one of the ``learned`` returns and none of the foreground
    ``points``: the object they track has just been learned as background.
    """
    gate_inv = inv2(gate_covariance(mix, cfg.model.rho, sensor_noise(cfg)))
    threshold = gate_threshold(cfg)

    def gated(z):
        if not len(z):
            return np.zeros(len(mix), dtype=bool)
        return np.any(gate_distance2(mix, z, gate_inv) < threshold, axis=1)

    return gated(learned) & ~gated(points)


def detect(pred: FilterState, sp: ScanPoints, cfg: TrackerConfig, diag: Diagnostics,
           pose: Pose2 | None = None,
           elsewhere: np.ndarray | None = None,
           foreground: np.ndarray | None = None) -> tuple[FilterState, Visibility]:
    """
    The detection model of the predicted components; drop those that are no object in
    view.

    Objects that left the field of view or range can never be seen again here: dropped
    rather than left to coast forever with p_D = 0. So are components the sensor would
    stand in, and those in view that expect far fewer returns than the beams they span,
    made of clutter: not objects, so their weight leaves the cardinality too.

    The model reads the components in the scanner's frame (at ``pose`` in the fixed
    frame); the centroid offsets it gives are turned back into the fixed frame. With
    several scanners, a component out of this one's view that another scanner looks at
    (``elsewhere``) is kept: this scan cannot see it, that one can. ``foreground`` marks
    the beams whose return is no background (:func:`sensing.detection.detection_model`).
    """
    view = pose or Pose2()
    vis = detection_model(mixture_to_inner(view, pred.mixture), sp, cfg, foreground)
    if vis.offset is not None:
        vis = replace(vis, offset=view.vectors_to_outer(vis.offset))
    if vis.outside is None:
        return pred, vis
    if elsewhere is not None:
        vis = replace(vis, outside=vis.outside & ~elsewhere)
    drop = vis.outside | vis.at_sensor | vis.sparse
    if not drop.any():
        return pred, vis
    at_sensor = vis.at_sensor & ~vis.outside
    sparse = vis.sparse & ~vis.outside & ~vis.at_sensor
    diag.left_view = int(np.count_nonzero(vis.outside))
    diag.at_sensor = int(np.count_nonzero(at_sensor))
    diag.sparse = int(np.count_nonzero(sparse))
    log_card = pred.log_card
    if diag.at_sensor or diag.sparse:
        log_card = thin_cardinality(log_card, float(pred.mixture.w[at_sensor | sparse].sum()))
    return replace(pred, mixture=pred.mixture.take(~drop), log_card=log_card), vis.take(~drop)


def update_tracks(pred: FilterState, tracks: TrackRecord, points: np.ndarray,
                  sp: ScanPoints, vis: Visibility, cfg: TrackerConfig, dt: float,
                  diag: Diagnostics, pose: Pose2 | None = None):
    """
    The filter update with the scan's detection model, then track management.

    The sensor model is evaluated on what the filter's pair updates return: each pair's
    p_D where its cell puts the object, and which births the scan could not have seen,
    both read in the scanner's frame (at ``pose`` in the fixed frame).
    """
    view = pose or Pose2()
    sensor = SensorTerms(vis.p_d, vis.rate_scale, vis.visible, vis.offset, vis.shadowed,
                         vis.in_open)
    clutter = (sp.beam_clutter_log_density(view.to_inner(points))
               if cfg.model.clutter_density == 'beam' else None)
    pairs = pair_updates(pred.mixture, points, cfg, sensor, sp.area, clutter)
    m_in, P_in, _ = kinematics_to_inner(view, pairs.m, pairs.P, None)
    pair_p_d = pair_detection_probability(mixture_to_inner(view, pred.mixture), pairs.comp,
                                          m_in, P_in, sp, cfg, vis.p_d)
    # the sensor is asked only about the births no pair it could have seen explains
    unseen = np.zeros(pairs.n_cells, dtype=bool)
    free = pairs.free_birth_cells(pair_p_d, cfg.birth.min_points)
    if len(free):
        unseen[free] = sparse_births(mixture_to_inner(view, pairs.births(free)), sp, cfg)
    # the warm-up shows the filter only what stands out: its clutter is not the scan's
    filt, facts = update(pred, pairs, sensor, pair_p_d, cfg, dt, diag, birth_unseen=unseen,
                         confirmed=tracks.confirmed_labels(cfg.extraction),
                         learn_clutter=not diag.warmup)
    return manage_tracks(filt, tracks, facts, cfg, dt, pred.next_label, diag)
