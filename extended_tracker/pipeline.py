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
through it, event ``unexplained_scan``, the reason in ``result.error``. A scan whose beams
differ from those the background was learned on (another count, reversed, finer) is used
with the background re-mapped to its beams by angle, event ``scan_layout_changed``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
import time

import numpy as np

from .config import TrackerConfig
from .diagnostics import Diagnostics
from .errors import ScanError
from .filter.state import FilterState, predict_state
from .frames.motion import frame_jump, scan_period
from .frames.pose import Placement, Pose2
from .scanners import anchored, mount_check, seen_elsewhere, silenced, View, with_scanner
from .sensing.background import BackgroundState
from .sensing.legs import LegEvidence, legs_seen, scan_config
from .sensing.scan import frame_of, scan_to_points, ScanPoints, stamp_ns
from .sensing.static_map import StaticMap
from .stages import detect, drop_absorbed, remove_background, update_tracks
from .tracks.estimates import Estimates
from .tracks.kinds import TrackKinds
from .tracks.record import TrackRecord
from .tracks.times import TrackTimes

EVENTS = ('repeated_stamp', 'time_backwards', 'time_gap', 'malformed_scan', 'foreign_frame',
          'unexplained_scan', 'zero_stamp', 'scan_layout_changed', 'frame_jump',
          'scanner_silent', 'mount_mismatch')



@dataclass(frozen=True)
class PipelineState:
    """
    Everything carried between scans.

    Attributes
    ----------
    filter : FilterState
        The filter's posterior.
    tracks : TrackRecord
        The record of the ids shown.
    background : BackgroundState or None
        The learned static background.
    last_stamp_ns, frame_id : int or None, str or None
        The last scan's stamp and the frame the pipeline is locked to.
    last_estimates : Estimates
        The objects shown for the last scan.
    moved : (k,) int64 array
        Labels seen to move: their returns are never learned as background.
    scans, elapsed : int, float
        Scans processed and seconds covered since start-up.
    static_map : StaticMap or None
        Static structure learned in the fixed frame (a placed scanner).
    pose, anchor : Pose2 or None
        The scanner's last pose in the fixed frame, and where the per-beam background was
        learned.
    moving : bool
        The scanner has moved in the fixed frame: the static map drops returns.
    times, kinds : TrackTimes, TrackKinds
        When each shown id was first shown and last updated by returns; what each is
        (motion and class history, :mod:`tracks.kinds`).
    scanner : str or None
        The frame of the scanner ``background``, ``anchor`` and ``pose`` belong to (the
        last scan's); ``others`` holds those of the other scanners placed in the fixed
        frame, ``{frame: Scanner}`` (:func:`scanners.with_scanner`).
    mount_mismatch : bool
        The scanners' mounts were found to disagree (said once).
    legs : LegEvidence
        Whether the scans show legs (:mod:`sensing.legs`).

    """

    filter: FilterState
    tracks: TrackRecord = field(default_factory=TrackRecord)
    background: BackgroundState | None = None
    last_stamp_ns: int | None = None
    frame_id: str | None = None
    last_estimates: Estimates = field(default_factory=Estimates.empty)
    moved: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    scans: int = 0
    elapsed: float = 0.0
    static_map: StaticMap | None = None
    pose: Pose2 | None = None
    anchor: Pose2 | None = None
    moving: bool = False
    times: TrackTimes = field(default_factory=TrackTimes)
    kinds: TrackKinds = field(default_factory=TrackKinds)
    scanner: str | None = None
    others: dict = field(default_factory=dict)
    view: View | None = None
    mount_mismatch: bool = False
    legs: LegEvidence = field(default_factory=LegEvidence)

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
    diagnostics : Diagnostics
        The scan's counts (a mapping).
    event : str or None
        One of :data:`EVENTS` when the scan was special.
    error : str or None
        What made the scan special, for the log: the reason of a malformed or unexplained
        scan, the gap or the step back in time, with the figures.
    processing_time : float
        Seconds spent in :func:`step`.
    pose : Pose2 or None
        The scanner's pose in the fixed frame (None: tracked in the scan frame, or the
        scan not used).
    age, since_detected : (k,) arrays
        Of each estimate: seconds since its id was first shown, and since returns last
        updated it (0 in a scan that updated it).
    scanner : str or None
        The frame of the scanner that took the scan (when placed in a fixed frame).
    motion, kind, kind_confidence : (k,) arrays
        Of each estimate: its motion state, class guess and how sure (:mod:`tracks.kinds`).

    """

    stamp_ns: int
    frame_id: str
    estimates: Estimates
    cardinality: np.ndarray
    expected_count: float
    points: np.ndarray
    background_points: np.ndarray
    diagnostics: Diagnostics
    event: str | None = None
    error: str | None = None
    processing_time: float = 0.0
    pose: Pose2 | None = None
    age: np.ndarray | None = None
    since_detected: np.ndarray | None = None
    scanner: str | None = None
    motion: np.ndarray | None = None
    kind: np.ndarray | None = None
    kind_confidence: np.ndarray | None = None

    def __post_init__(self):
        # a result made by hand (a test, a tool) without the times and kinds: none known, 0
        for name in ('age', 'since_detected', 'motion', 'kind', 'kind_confidence'):
            if getattr(self, name) is None:
                setattr(self, name, np.zeros(len(self.estimates),
                                             np.uint8 if name in ('motion', 'kind') else float))


def step(state: PipelineState, scan, cfg: TrackerConfig, arrival_ns: int | None = None,
         place: Placement | None = None) -> tuple[PipelineState, StepResult]:
    """
    Carry one LaserScan-like message through the whole chain.

    ``place``, when given, is where the scan was taken: the tracks are kept in its fixed
    frame, the scanner at its pose there (the caller looked it up at the scan's stamp).
    Without it they are kept in the scan's own frame, the scanner standing still.

    convert -> legs seen? -> background -> predict -> p_D -> pair updates -> update ->
    track management.

    ``arrival_ns``, when given, is when the scan arrived (the node's clock, a bag's record
    time): a scan whose header stamp is zero (a driver that does not set it) is taken at
    that time instead, event ``zero_stamp``. Without it every scan after the first would
    repeat the first one's stamp, and none would be used.

    Returns the new state and a :class:`StepResult`; never raises on bad sensor data.
    ``result.diagnostics`` holds the counts of every stage (:class:`Diagnostics`).
    """
    t0 = time.perf_counter()
    scan_in = _accept(state, scan, cfg, arrival_ns, t0, place)
    if isinstance(scan_in, StepResult):
        return state, scan_in
    sp, dt, event, error = scan_in.points, scan_in.dt, scan_in.event, scan_in.error
    state, quiet = silenced(scan_in.state, scan_in.stamp_ns, cfg.timing.max_gap)
    if quiet:
        event, error = _with_event(event, error, 'scanner_silent', _silent(quiet, state))
    pose = place.pose if place is not None else None
    state, leaving = anchored(state, pose, scan_in.event == 'frame_jump')
    diag = _scan_counts(sp)
    legs = legs_seen(state.legs, sp, scan_in.own_dt, cfg, state.scanner)
    scan_cfg = scan_config(cfg, legs)
    diag.legs = int(legs.seen)
    if _layout_changed(state.background, sp, cfg):
        event, error = _with_event(event, error, 'scan_layout_changed',
                                   _layout_change(state.background, sp))
    fg = remove_background(state, scan_in.tracks, sp, dt, cfg, diag, pose, scan_in.own_dt)
    pred = predict_state(scan_in.filter, dt, cfg)
    pred = drop_absorbed(pred, fg.learned, fg.points, cfg, diag,
                         first_new=scan_in.filter.next_label)
    pred, vis = detect(pred, sp, cfg, diag, pose,
                       seen_elsewhere(state, pred.mixture.m[:, :2]), fg.beams)
    filt, tracks, estimates = update_tracks(pred, scan_in.tracks, fg.points, sp, vis, scan_cfg,
                                            dt, diag, pose)
    if diag.unexplained:
        event, error = _with_event(event, error, 'unexplained_scan',
                                   _unexplained(len(fg.points), cfg))
    times = state.times.updated(estimates, scan_in.stamp_ns)
    kinds = state.kinds.updated(estimates, dt, fg.moved, tracks.pairs.ravel())
    new_state = replace(state, filter=filt, tracks=tracks,
                        background=None if leaving else fg.background,
                        static_map=fg.static_map, last_stamp_ns=scan_in.stamp_ns,
                        frame_id=scan_in.frame_id, last_estimates=estimates, moved=fg.moved,
                        scans=state.scans + 1, elapsed=state.elapsed + dt, pose=pose,
                        times=times, kinds=kinds, legs=legs,
                        view=pose and View(pose, sp.angle_lo, sp.angle_hi, sp.range_max,
                                           sp.full_turn))
    new_state, mismatch = mount_check(new_state)
    if mismatch:
        event, error = _with_event(event, error, 'mount_mismatch', mismatch)
    card, mean = _card_of(new_state)
    return new_state, StepResult(scan_in.stamp_ns, scan_in.frame_id, estimates, card, mean,
                                 fg.points, fg.background_points, diag, event, error,
                                 time.perf_counter() - t0, pose,
                                 *times.of(estimates, scan_in.stamp_ns),
                                 state.scanner if pose is not None else None,
                                 *kinds.of(estimates))


@dataclass(frozen=True)
class _Accepted:
    """A scan placed in time (:func:`_accept`): its points, stamp, frame and period, the
    filter and record to go on from (fresh after a restart), its event and reason, and
    the state with its scanner's own parts (:func:`scanners.with_scanner`)."""

    points: ScanPoints
    stamp_ns: int
    frame_id: str
    dt: float
    filter: FilterState
    tracks: TrackRecord
    event: str | None
    error: str | None
    state: PipelineState
    own_dt: float


def _accept(state: PipelineState, scan, cfg: TrackerConfig, arrival_ns, t0,
            place: Placement | None):
    """
    Read the scan's header and beams and place it in time: either the held result of a
    scan that is not used (malformed, foreign frame, repeated stamp), or the scan
    :class:`_Accepted`, the filter and the record reset on a step back in time, a gap or
    a jump of the fixed frame.
    """
    try:
        now = stamp_ns(scan)
        frame = frame_of(scan)
    except (AttributeError, TypeError, ValueError) as err:
        return _repeat(state, state.last_stamp_ns or 0, state.frame_id or '',
                       'malformed_scan', f'unreadable header: {err}', t0)
    now, zero_stamp = _scan_time(now, arrival_ns)
    try:
        sp = scan_to_points(scan, cfg.scan.min_range, cfg.scan.max_range,
                            cfg.scan.range_max_inclusive)
    except ScanError as err:
        return _repeat(state, now, frame, 'malformed_scan', str(err), t0)
    scanner_ns = state.last_stamp_ns
    if place is not None:
        state, scanner_ns = with_scanner(state, frame)
        frame = place.frame
    if state.frame_id is not None and frame != state.frame_id:
        # tracks in another frame are not comparable: the previous estimates stand
        return _repeat(state, now, state.frame_id, 'foreign_frame',
                       f'frame {frame!r} is not the tracked frame {state.frame_id!r}', t0)
    if now == scanner_ns:                   # another scanner's scan may share the stamp
        return _repeat(state, now, frame, 'repeated_stamp',
                       'the same stamp as the previous scan: not used again', t0)
    dt, event, error = scan_period(state.last_stamp_ns, now, cfg)
    own_dt = dt if scanner_ns in (None, state.last_stamp_ns) or event else (
        (now - scanner_ns) * 1e-9)
    if event is None and place is not None and scanner_ns is not None:
        event, error = frame_jump(state.pose, place.pose, own_dt, cfg)
    filt, tracks = state.filter, state.tracks
    if event is not None:
        filt, tracks = _reset(filt, cfg), TrackRecord()
    elif zero_stamp:
        event = 'zero_stamp'
        error = ('the header stamp is zero (a driver that does not set it?): the scan is '
                 'taken at its arrival time')
    return _Accepted(sp, now, frame, dt, filt, tracks, event, error, state, own_dt)


def _scan_counts(sp: ScanPoints) -> Diagnostics:
    """A scan's diagnostics with its beams, masked beams and valid returns counted."""
    diag = Diagnostics(detections=len(sp.points), beams=len(sp.angles))
    for kind, count in sp.masked.items():
        setattr(diag, f'masked_{kind}', count)
    return diag


def _with_event(event, error, new_event: str, why: str):
    """The event and reason of a scan that also met ``new_event`` (a restart outranks it;
    a zero stamp, every scan from some drivers, does not); both reasons are kept."""
    event = new_event if event in (None, 'zero_stamp') else event
    return event, why if error is None else f'{error}; {why}'


def _layout_changed(background, sp: ScanPoints, cfg: TrackerConfig) -> bool:
    """Whether the scan's beams differ from those the background was learned on."""
    return (cfg.background.enabled and background is not None and len(sp.angles) > 0
            and not background.matches(sp))


def _silent(frames: list, state: PipelineState) -> str:
    """The reason of event ``scanner_silent``."""
    return (f'no scan from {", ".join(frames)} for over timing.max_gap: tracking goes on '
            f'with {state.scanner}')


def _unexplained(n_points: int, cfg: TrackerConfig) -> str:
    """The reason of event ``unexplained_scan``."""
    return (f'no partition of the {n_points} returns is possible (more objects than '
            f'model.n_max = {cfg.model.n_max}?): the tracks were predicted through it')


def _layout_change(background, sp: ScanPoints) -> str:
    """The reason of event ``scan_layout_changed``."""
    return (f'{len(sp.angles)} beams over [{sp.angle_lo:.4f}, {sp.angle_hi:.4f}] rad where '
            f'the background was learned on {len(background.angles)}: what was learned is '
            f're-mapped to the new beams by angle')


def _card_of(state: PipelineState):
    card = np.exp(state.filter.log_card)
    return card, float(np.sum(np.arange(len(card)) * card))


def _repeat(state, scan_stamp, frame, event, error, t0):
    card, mean = _card_of(state)
    return StepResult(scan_stamp, frame, state.last_estimates, card, mean, np.zeros((0, 2)),
                      np.zeros((0, 2)), Diagnostics(), event, error, time.perf_counter() - t0,
                      None, *state.times.of(state.last_estimates, scan_stamp), None,
                      *state.kinds.of(state.last_estimates))


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


def step_placed(state: PipelineState, scan, cfg: TrackerConfig, arrival_ns: int | None,
                placed=None) -> tuple[PipelineState, StepResult]:
    """
    :func:`step` on a scan out of :class:`frames.placing.ScanPlacer` (``placed``; without
    it, the scan is tracked in its own frame), the call of the node and the replay alike
    (:func:`step` is looked up here at each call: a test can stand in for it). A dropped
    scan is
    answered with the previous estimates and its event; one that moves the tracks to the
    fixed frame first restarts them (ids continue). The queue's notices (which frame the
    tracks are in) are the caller's to say; they are no event of the scan.
    """
    if placed is None:
        return step(state, scan, cfg, arrival_ns)
    if placed.dropped:
        return state, held(state, scan, placed.event, placed.error, arrival_ns)
    if placed.event == 'fixed_frame_found':
        state = reset(state, cfg)
    return step(state, scan, cfg, arrival_ns, placed.place)


def _scan_time(stamp: int, arrival_ns: int | None) -> tuple[int, bool]:
    """The time a scan is taken at, and whether its stamp was zero and the arrival time
    (when known) stands in for it."""
    zero = stamp == 0 and arrival_ns is not None
    return (int(arrival_ns) if zero else stamp), zero


def _reset(filt: FilterState, cfg: TrackerConfig) -> FilterState:
    """A fresh filter whose labels continue after the old ones (ids are never reused)."""
    return FilterState.initial(cfg, next_label=filt.next_label)


def reset(state: PipelineState, cfg: TrackerConfig) -> PipelineState:
    """
    Start over as at start-up, with labels continuing after the old ones (ids are never
    reused): no tracks, no learned background or static map (the warm-up runs again), no
    frame lock. For a scanner that was moved, or a new session in the same run.
    """
    return PipelineState(_reset(state.filter, cfg), last_stamp_ns=state.last_stamp_ns)


__all__ = ['PipelineState', 'StepResult', 'step', 'step_placed', 'held', 'reset', 'EVENTS', 'ScanPoints']
