"""
The per-scan pipeline: the one function the node, the bag replay, the tests and the
benchmarks all call.

``step(state, scan, config) -> (state, result)``: convert, background, p_D, predict,
partition, update, reduce, extract. Pure numpy/scipy; the same scans give identical
output on every run (only ``result.processing_time`` varies).

Time handling (stamps from the scan header):

- first scan, or first after a reset: ``dt = timing.default_dt``;
- a repeated stamp: the scan is not used again; the previous estimates are returned
  with event ``repeated_stamp`` (never a zero-dt double update);
- a stamp earlier than the previous one (a bag looping, a clock jump): the filter is
  reset (tracks dropped, learned background kept, new labels continue after the old
  ones so an id is never reused) and the scan processed as a first scan; event
  ``time_backwards``;
- a gap longer than ``timing.max_gap``: the filter is re-initialised the same way; event
  ``time_gap``;
- a zero stamp (a driver that does not set it), when the caller says when the scan
  arrived: that time is used; event ``zero_stamp``.

Malformed scans raise nothing out of :func:`step`: they give a result with the previous
estimates and event ``malformed_scan``, the reason in ``result.error``. The pipeline locks
onto the first scan's ``frame_id``; a scan from another frame is answered the same way
with event ``foreign_frame``. A scan that no partition of its returns can explain (every
one holds more objects than ``model.n_max``) updates nothing: the tracks are predicted
through it, event ``unexplained_scan``, the reason in ``result.error``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
import time

import numpy as np

from .config import TrackerConfig
from .cphd import thin_cardinality
from .errors import ScanError
from .ggiw import gate_covariance, gate_distance2, inv2
from .sensing.background import BackgroundState, beams_near_tracks, update_background
from .sensing.scan import frame_of, INVALID_KINDS, scan_to_points, ScanPoints, stamp_ns
from .sensing.shadow import detection_model, pair_detection_probability, sparse_births
from .state import Estimates, FilterState, find_sorted, StepDiagnostics
from .tracker import gate_threshold, predict_state, sensor_noise, update_state

EVENTS = ('repeated_stamp', 'time_backwards', 'time_gap', 'malformed_scan', 'foreign_frame',
          'unexplained_scan', 'zero_stamp')


@dataclass(frozen=True)
class PipelineState:
    """Everything carried between scans."""

    filter: FilterState
    background: BackgroundState | None = None
    last_stamp_ns: int | None = None
    frame_id: str | None = None
    last_estimates: Estimates = field(default_factory=Estimates.empty)
    moved: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))  # see step
    scans: int = 0
    elapsed: float = 0.0

    @staticmethod
    def initial(cfg: TrackerConfig) -> 'PipelineState':
        return PipelineState(FilterState.initial(cfg))


@dataclass
class StepResult:
    """
    Output of one scan.

    Attributes
    ----------
    stamp_ns : int
    frame_id : str
    estimates : Estimates
    cardinality : (N_max + 1,) array, posterior pmf
    expected_count : float
    points : (m, 2) array
        Detections the filter used (after background removal).
    background_points : (k, 2) array
        Detections dropped as background.
    diagnostics : dict
        Counts and the step time; see :func:`step`.
    event : str or None
        One of :data:`EVENTS` when the scan was special.
    error : str or None
        What made the scan special, for the log: the reason of a malformed or unexplained
        scan, the gap or the step back in time, with the figures.
    processing_time : float
        Seconds spent in :func:`step`.

    """

    stamp_ns: int
    frame_id: str
    estimates: Estimates
    cardinality: np.ndarray
    expected_count: float
    points: np.ndarray
    background_points: np.ndarray
    diagnostics: dict
    event: str | None = None
    error: str | None = None
    processing_time: float = 0.0


# the filter's own counts, copied from its StepDiagnostics (detections are counted here)
_FILTER_DIAG = tuple(f.name for f in fields(StepDiagnostics) if f.name != 'detections')
_DIAG = {'detections': 0, 'background_dropped': 0, 'warmup': 0, 'left_view': 0,
         'at_sensor': 0, 'sparse': 0, 'absorbed': 0, **dict.fromkeys(_FILTER_DIAG, 0),
         'beams': 0, **{f'masked_{k}': 0 for k in INVALID_KINDS}}
_MASKED_KEY = {k: f'masked_{k}' for k in INVALID_KINDS}


def _diag_template():
    return dict(_DIAG)


def _absorbed(mix, learned: np.ndarray, points: np.ndarray, cfg: TrackerConfig) -> np.ndarray:
    """
    The components that gate (``ggiw.gate_pairs``' gate) one of the ``learned`` returns
    and none of the foreground ``points``: the object they track has just been learned as
    background.
    """
    gi = inv2(gate_covariance(mix, cfg.model.rho, sensor_noise(cfg)))
    threshold = gate_threshold(cfg)

    def gated(z):
        if not len(z):
            return np.zeros(len(mix), dtype=bool)
        return np.any(gate_distance2(mix, z, gi) < threshold, axis=1)

    return gated(learned) & ~gated(points)


def _card_of(state: PipelineState):
    card = np.exp(state.filter.log_card)
    return card, float(np.sum(np.arange(len(card)) * card))


def _repeat(state, scan_stamp, frame, event, error, t0, diag=None):
    card, mean = _card_of(state)
    return StepResult(scan_stamp, frame, state.last_estimates, card, mean, np.zeros((0, 2)),
                      np.zeros((0, 2)), diag or _diag_template(), event, error,
                      time.perf_counter() - t0)


def held(state: PipelineState, scan, event: str, error: str,
         arrival_ns: int | None = None) -> StepResult:
    """
    The answer to a scan the caller could not carry through :func:`step` (the node, when
    the pipeline itself fails): the previous estimates, with the scan's stamp (the
    arrival time for a zero one, the last stamp for an unreadable one) in the tracked
    frame, so the scan still gets its publication.
    """
    try:
        now, _ = _scan_time(stamp_ns(scan), arrival_ns)
        frame = frame_of(scan)
    except (AttributeError, TypeError, ValueError):
        now, frame = state.last_stamp_ns or 0, ''
    return _repeat(state, now, state.frame_id or frame, event, error, time.perf_counter())


def _scan_time(stamp: int, arrival_ns: int | None) -> tuple[int, bool]:
    """The time a scan is taken at, and whether its stamp was zero and the arrival time
    (when known) stands in for it."""
    zero = stamp == 0 and arrival_ns is not None
    return (int(arrival_ns) if zero else stamp), zero


def _reset(filt: FilterState, cfg: TrackerConfig) -> FilterState:
    """A fresh filter whose labels continue after the old ones (ids are never reused)."""
    return replace(FilterState.initial(cfg), next_label=filt.next_label)


def reset(state: PipelineState, cfg: TrackerConfig) -> PipelineState:
    """
    Start over as at start-up, with labels continuing after the old ones (ids are never
    reused): no tracks, no learned background (the warm-up runs again), no frame lock.
    For a scanner that was moved, or a new session in the same run.
    """
    return PipelineState(_reset(state.filter, cfg), last_stamp_ns=state.last_stamp_ns)


def step(state: PipelineState, scan, cfg: TrackerConfig,
         arrival_ns: int | None = None) -> tuple[PipelineState, StepResult]:
    """
    Carry one LaserScan-like message through the whole chain.

    ``arrival_ns``, when given, is when the scan arrived (the node's clock, a bag's record
    time): a scan whose header stamp is zero (a driver that does not set it) is taken at
    that time instead, event ``zero_stamp``. Without it every scan after the first would
    repeat the first one's stamp, and none would be used.

    Returns the new state and a :class:`StepResult`; never raises on bad sensor data.
    ``result.diagnostics`` holds: ``beams``, ``masked_<kind>`` for each invalid-beam kind,
    ``detections`` (valid returns), ``background_dropped``, ``warmup`` (1 while the
    background warm-up runs), ``left_view`` (components dropped as out of the field of
    view), ``at_sensor`` (components dropped because the sensor lay within their outline),
    ``sparse`` (components in view dropped because they expected fewer returns than
    ``detection.min_fill`` of the beams they span; ``sparse_births``, births refused so),
    ``absorbed`` (components dropped because the returns they stood on were just
    learned as background), ``partitions``, ``cells``,
    ``pairs``, ``components``, ``births``, ``capped_partitions``, ``capped_cells``,
    ``capped_components``, ``oversized`` (components dropped as too large or too
    uncertain), ``fused_labels`` (labels found to track an object another label
    tracks), ``joined_labels`` (labels joined into another as parts of one object,
    ``reduction.pair_scans``), ``relabelled`` (labels given a new id because they jumped
    farther than ``extraction.max_speed`` allows), ``handed_over`` (lost ids passed on to
    a new object where the lost one would be), ``grouped`` (thin contour pieces
    reported as part of another's object), ``held`` (components held from a miss while
    wholly in shadow) and ``unexplained`` (1 when no partition explained the scan).
    """
    t0 = time.perf_counter()
    try:
        now = stamp_ns(scan)
        frame = frame_of(scan)
    except (AttributeError, TypeError, ValueError) as err:
        return state, _repeat(state, state.last_stamp_ns or 0, state.frame_id or '',
                              'malformed_scan', f'unreadable header: {err}', t0)
    now, zero_stamp = _scan_time(now, arrival_ns)
    try:
        sp = scan_to_points(scan, cfg.scan.min_range, cfg.scan.max_range,
                            cfg.scan.range_max_inclusive)
    except ScanError as err:
        return state, _repeat(state, now, frame, 'malformed_scan', str(err), t0)

    if state.frame_id is not None and frame != state.frame_id:
        # The tracker is locked to the first scan's frame: tracks in another frame are not
        # comparable. The scan is not used; the previous estimates stand (in their frame).
        return state, _repeat(state, now, state.frame_id, 'foreign_frame',
                              f'frame {frame!r} is not the tracked frame {state.frame_id!r}',
                              t0)
    event = error = None
    filt = state.filter
    background = state.background
    if state.last_stamp_ns is None:
        dt = cfg.timing.default_dt
    elif now == state.last_stamp_ns:
        return state, _repeat(state, now, frame, 'repeated_stamp',
                              'the same stamp as the previous scan: not used again', t0)
    elif now < state.last_stamp_ns:
        event = 'time_backwards'
        error = (f'stamp {(state.last_stamp_ns - now) * 1e-9:.3f} s before the previous '
                 f'scan\'s (a bag that looped, or a clock jump?): tracks restarted')
        filt = _reset(filt, cfg)
        dt = cfg.timing.default_dt
    else:
        dt = (now - state.last_stamp_ns) * 1e-9
        if dt > cfg.timing.max_gap:
            event = 'time_gap'
            error = (f'{dt:.3f} s since the previous scan, over timing.max_gap '
                     f'({cfg.timing.max_gap:g} s): tracks restarted')
            filt = _reset(filt, cfg)
            dt = cfg.timing.default_dt
    if zero_stamp and event is None:
        event = 'zero_stamp'
        error = ('the header stamp is zero (a driver that does not set it?): the scan is '
                 'taken at its arrival time')
    diag = _diag_template()
    diag['beams'] = len(sp.angles)
    for k, v in sp.masked.items():
        diag[_MASKED_KEY[k]] = v
    diag['detections'] = len(sp.points)

    # background: drop static returns; never learn those of tracks that have moved
    points = sp.points
    bg_points = np.zeros((0, 2))
    learned = np.zeros((0, 2))             # returns whose beams were learned this scan
    moved = state.moved
    if cfg.background.enabled and len(sp.angles):
        est = state.last_estimates
        bgc = cfg.background
        # confirmed, person-sized tracks that have moved protect their returns; a label
        # seen to move keeps protecting while it lives, though its report record (and
        # travel) restarts after a scan it was not reported in (a walker who stops just
        # after a scan with both legs hidden)
        travel = filt.confirmed_travel(est.label, cfg.extraction)
        moved = np.union1d(moved[find_sorted(filt.shown, moved)[1]],
                           est.label[travel >= bgc.moved_distance])
        major = est.axes()[0] if len(est) else np.zeros(0)
        guard = find_sorted(moved, est.label)[1] & (major <= bgc.protect_semi_axis)
        prot, near = beams_near_tracks(sp, est.m[:, :2], major, bgc.track_gate, guard)
        background, keep = update_background(background, sp, dt, bgc, prot, near)
        bg_points = points[~keep]
        learned = points[background.learned[sp.beam]]
        points = points[keep]
        diag['background_dropped'] = len(keep) - int(np.count_nonzero(keep))
        if state.elapsed + dt <= cfg.background.warmup:
            # warm-up: learn the background before tracking anything, so walls are never
            # tracked; the filter runs predict-only steps meanwhile
            diag['warmup'] = 1
            bg_points = np.vstack([bg_points, points])
            points = np.zeros((0, 2))

    pred = predict_state(filt, dt, cfg)
    if len(learned) and len(pred.mixture) and not diag['warmup']:
        # tracks that stood on returns just learned as background, with no foreground
        # return left: dropped, not left to coast onto a neighbour's returns (the region
        # births of this scan stay), and their weight taken from the cardinality
        mix = pred.mixture
        on_bg = _absorbed(mix, learned, points, cfg) & (mix.label < filt.next_label)
        if np.any(on_bg):
            pred = replace(pred, mixture=mix.take(~on_bg),
                          log_card=thin_cardinality(pred.log_card, float(mix.w[on_bg].sum())))
            diag['absorbed'] = int(np.count_nonzero(on_bg))
    vis = detection_model(pred.mixture, sp, cfg)
    drop = None if vis.outside is None else vis.outside | vis.at_sensor | vis.sparse
    if drop is not None and np.any(drop):
        # objects that left the field of view or range can never be seen again here:
        # dropped rather than left to coast forever with p_D = 0. So are components the
        # sensor would stand in, and those in view that expect far fewer returns than the
        # beams they span, made of clutter: not objects, so their weight leaves the
        # cardinality too (as the absorbed ones' does)
        at_sensor = vis.at_sensor & ~vis.outside
        sparse = vis.sparse & ~vis.outside & ~vis.at_sensor
        diag['left_view'] = int(np.count_nonzero(vis.outside))
        diag['at_sensor'] = int(np.count_nonzero(at_sensor))
        diag['sparse'] = int(np.count_nonzero(sparse))
        log_card = pred.log_card
        if diag['at_sensor'] or diag['sparse']:
            not_objects = at_sensor | sparse
            log_card = thin_cardinality(log_card, float(pred.mixture.w[not_objects].sum()))
        pred = replace(pred, mixture=pred.mixture.take(~drop), log_card=log_card)
        vis = vis.take(~drop)

    def pair_p_d(mix, comp, m_new, P_new):
        return pair_detection_probability(mix, comp, m_new, P_new, sp, cfg, vis.p_d)

    def no_birth(births):
        return sparse_births(births, sp, cfg)

    clutter = (sp.beam_clutter_log_density(points) if cfg.model.clutter_density == 'beam'
               else None)
    new_filter, estimates, fdiag = update_state(
        pred, points, vis.p_d, cfg, rate_scale=vis.rate_scale, clutter_area=sp.area,
        visibility=vis.visible, centroid_offset=vis.offset, pair_p_d=pair_p_d,
        clutter_log_density=clutter, shadowed=vis.shadowed, no_birth=no_birth)
    for k in _FILTER_DIAG:
        diag[k] = getattr(fdiag, k)
    if fdiag.unexplained:
        # a restart outranks it; a zero stamp (every scan, from a driver) does not
        event = 'unexplained_scan' if event in (None, 'zero_stamp') else event
        why = (f'no partition of the {len(points)} returns is possible (more objects than '
               f'model.n_max = {cfg.model.n_max}?): the tracks were predicted through it')
        error = why if error is None else f'{error}; {why}'
    new_state = replace(state, filter=new_filter, background=background, last_stamp_ns=now,
                       frame_id=frame, last_estimates=estimates, moved=moved,
                       scans=state.scans + 1,
                       elapsed=state.elapsed + dt)
    card, mean = _card_of(new_state)
    result = StepResult(now, frame, estimates, card, mean, points, bg_points, diag, event,
                        error, 0.0)
    result.processing_time = time.perf_counter() - t0
    return new_state, result


__all__ = ['PipelineState', 'StepResult', 'step', 'held', 'reset', 'EVENTS', 'ScanPoints']
