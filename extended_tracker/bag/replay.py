"""
Bag replay: LaserScans from a bag through :func:`pipeline.step` into a new MCAP bag.

The output holds the node's topics: ``/scan`` (the input scans as read, in ROS 2 form
whatever the input bag's topic and ROS version, a ROS 1 ``frame_id``'s leading ``/``
dropped), ``/tracks`` (ExtendedObjectArray) and ``/tracks/markers`` (MarkerArray),
stamped with the scan stamps, with the message definitions stored so ``ros2 bag play``
on a Jazzy install replays it (and the installed RViz view shows it as it shows the live
node). It is written under its own name inside a hidden staging folder beside the target
and moved into place only when complete: an interrupted replay leaves no bag.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math
from pathlib import Path
import sys
import time

import numpy as np

from .. import stopping
from ..config import TrackerConfig
from ..errors import BagError
from ..frames.buffer import TransformBuffer
from ..frames.placing import ScanPlacer
from ..pipeline import PipelineState, step, step_placed
from ..report.messages import markers_data, SHAPE_RECTANGLE, shapes, tracks_data
from ..sensing.scan import stamp_ns
from ..tracks.travel import Travel
from .bagio import (
    build_message, check_output, MARKERS_TYPE, message_typestore, open_scans, remove_stale_stages,
    scan_data, SCAN_TYPE, staged_bag, TRACKS_TYPE,
)
from .scanners import choose_frame, Mounts, one_per_scanner
from .transforms import feed, is_static, tf_connections, tf_data, TF_TYPE

SCAN_TOPIC = '/scan'
TRACKS_TOPIC = '/tracks'
MARKERS_TOPIC = '/tracks/markers'


@dataclass
class ReplaySummary:
    """Figures of a replay."""

    scans: int = 0
    valid_detections: int = 0
    distinct_ids: int = 0
    moving_ids: int = 0
    mean_count: float = 0.0
    max_count: int = 0
    median_ms: float = 0.0
    p99_ms: float = 0.0
    events: dict = field(default_factory=dict)
    first_reasons: dict = field(default_factory=dict)   # event -> its first scan's reason
    renamed_frames: dict = field(default_factory=dict)  # frame_id as read -> as written
    removed_stages: list = field(default_factory=list)  # left by runs that were killed
    topic: str = ''
    output: str = ''
    plot: str = ''
    fixed_frame: str = ''               # '' : the scan frame
    frame_why: str = ''
    notes: list = field(default_factory=list)   # topics that share a frame
    legs_from: int | None = None        # the first scan that saw legs (sensing.legs)

    def lines(self) -> list[str]:
        per_scan = self.valid_detections / max(self.scans, 1)
        ev = ', '.join(f'{k} {v}' for k, v in sorted(self.events.items())) or 'none'
        return [
            f'scans            {self.scans} (topic {self.topic})',
            f'tracked in       {self.fixed_frame or "the scan frame"} ({self.frame_why})',
        ] + [f'scanners         {note}' for note in self.notes] + [
            f'valid detections {self.valid_detections} ({per_scan:.1f} per scan)',
            f'distinct ids     {self.distinct_ids} ({self.moving_ids} moved more than 1 m)',
            f'objects per scan mean {self.mean_count:.2f}, max {self.max_count}',
            f'legs seen        {self.legs_seen()}',
            f'time per scan    median {self.median_ms:.2f} ms, p99 {self.p99_ms:.2f} ms',
            f'events           {ev}',
        ] + [f'  first {k}: {why}' for k, why in sorted(self.first_reasons.items())] + [
            f'frame_id         {old!r} written as {new!r} (tf2 in ROS 2 refuses a leading /)'
            for old, new in sorted(self.renamed_frames.items())] + [
            f'removed          {stage} (the staging folder of an earlier run that was killed)'
            for stage in self.removed_stages]

    def legs_seen(self) -> str:
        if self.legs_from is None:
            return 'no (a scanner at body height, or no one walked by)'
        return f'from scan {self.legs_from} on (a scanner at leg height: partition.leg_gap)'


class _Progress:
    """A one-line progress bar on a terminal (nothing when not a terminal)."""

    def __init__(self, total: int, stream=None):
        self.total = max(total, 1)
        self.stream = stream or sys.stderr
        self.on = self.stream.isatty()
        self.last = 0.0

    def update(self, done: int):
        now = time.monotonic()
        if not self.on or (now - self.last < 0.1 and done < self.total):
            return
        self.last = now
        frac = done / self.total
        bar = '#' * int(30 * frac)
        self.stream.write(f'\r[{bar:<30}] {done}/{self.total} scans')
        self.stream.flush()

    def close(self):
        if self.on:
            self.stream.write('\n')


def ros2_frame_id(frame_id: str) -> str:
    """``frame_id`` as tf2 in ROS 2 takes it: ROS 1's leading ``/`` dropped (``/laser``
    names the frame ``laser``; RViz2 shows nothing in a frame that starts with ``/``)."""
    name = frame_id.lstrip('/')
    return name if name else frame_id


@dataclass(frozen=True)
class Untracked:
    """What :func:`replay_results` yields for a scan of a topic it does not track (a
    scanner's second topic): its topic and record time, for the output bag."""

    topic: str
    record_ns: int


def replay_results(input_path, cfg: TrackerConfig, scan_topic=None,
                   renamed_frames: dict | None = None, fixed_frame: str = '',
                   transforms: list | None = None, mounts: Mounts = Mounts(),
                   untracked: bool = False):
    """
    Yield ``(scan_message, StepResult)`` for every LaserScan of a bag, in time order.

    A scan whose ``frame_id`` has ROS 1's leading ``/`` is tracked and yielded with the
    frame as ROS 2 names it (:func:`ros2_frame_id`); ``renamed_frames``, when given,
    collects each such name as read and as used.

    With a ``fixed_frame`` (:func:`choose_fixed_frame`) the bag's ``/tf`` and
    ``/tf_static`` are read with the scans, and each scan is placed in the fixed frame at
    its stamp (:class:`frames.placing.ScanPlacer`, waiting ``tf.timeout`` of record time
    for its transform); ``transforms``, when given, collects ``(topic, record_ns, msg)``
    of every transform message read, for the output bag. Every scanner's scans are
    tracked (one topic of those that share a frame), placed by the bag's transforms and
    the ``mounts``. With ``untracked``, the scans of topics not tracked (a scanner's
    second topic) are yielded too, as ``(scan, Untracked)``.
    """
    reader, every = open_scans(input_path, scan_topic)
    conns = one_per_scanner(reader, every)[0]
    extra = [c for c in every if c not in conns] if untracked else []
    tf_conns = tf_connections(reader) if fixed_frame else []
    buffer = TransformBuffer(cache_ns=None)
    mounts.add_to(buffer)
    placer = ScanPlacer(buffer.lookup, fixed_frame, cfg.tf.timeout, cfg.tf.max_tilt,
                        cfg.timing.latency, cfg.timing.max_gap)
    try:
        state = PipelineState.initial(cfg)
        for conn, record_ns, raw in reader.messages(connections=conns + tf_conns + extra):
            stopping.check()
            msg = _decode(reader, raw, conn)
            if conn in extra:
                yield _renamed(msg, renamed_frames), Untracked(conn.topic, record_ns)
                continue
            if conn in tf_conns:
                feed(buffer, msg, is_static(conn))
                if transforms is not None:
                    transforms.append((conn.topic, record_ns, msg))
            elif not fixed_frame:
                # the record time stands in for a zero header stamp (event zero_stamp)
                state, result = step(state, _renamed(msg, renamed_frames), cfg,
                                     arrival_ns=record_ns)
                yield msg, result
                continue
            elif _frame_of(msg) is None:        # unreadable: step says so (malformed_scan)
                state, result = step(state, msg, cfg, arrival_ns=record_ns)
                yield msg, result
                continue
            else:
                scan = _renamed(msg, renamed_frames)
                placer.push(scan, _stamp_or(scan, record_ns), scan.header.frame_id, record_ns)
            for placed in placer.ready(record_ns):
                state, result = step_placed(state, placed.scan, cfg, placed.arrival_ns, placed)
                yield placed.scan, result
        for placed in placer.flush():
            state, result = step_placed(state, placed.scan, cfg, placed.arrival_ns, placed)
            yield placed.scan, result
    finally:
        reader.close()


def _decode(reader, raw, conn):
    try:
        return reader.deserialize(raw, conn.msgtype)
    except Exception as err:  # a corrupt record: say which, stop cleanly
        raise BagError(f'cannot decode a {conn.msgtype} on {conn.topic}: {err}') from err


def _renamed(scan, renamed_frames):
    frame = ros2_frame_id(scan.header.frame_id)
    if frame != scan.header.frame_id:
        if renamed_frames is not None:
            renamed_frames.setdefault(scan.header.frame_id, frame)
        scan.header.frame_id = frame
    return scan


def _frame_of(scan) -> str | None:
    try:
        frame = scan.header.frame_id
    except AttributeError:
        return None
    return frame if isinstance(frame, str) else None


def _stamp_or(scan, record_ns: int) -> int:
    """The scan's stamp, or its record time when the stamp is zero."""
    try:
        stamp = stamp_ns(scan)
    except (AttributeError, TypeError, ValueError):
        return record_ns
    return stamp or record_ns


def choose_fixed_frame(input_path, scan_topic, cfg: TrackerConfig, asked: str | None = None,
                       mounts: Mounts = Mounts()):
    """
    ``(frame, why, topics, notes)``: the frame a replay tracks in and why
    (:func:`scanners.choose_frame`), the scan topics tracked (``{topic: frame}``, one per
    scanner) and what was said of topics that share a frame.
    """
    reader, conns = open_scans(input_path, scan_topic)
    try:
        conns, topics, notes = one_per_scanner(reader, conns)
        frame, why = choose_frame(reader, sorted(set(topics.values())), cfg, mounts, asked)
    finally:
        reader.close()
    return frame, why, topics, notes


def replay(input_path, output_path, cfg: TrackerConfig, scan_topic=None, plot_path=None,
           progress: bool = True, fixed_frame: str | None = None,
           mounts: Mounts = Mounts()) -> ReplaySummary:
    """
    Replay a bag into a new MCAP bag; optionally draw the run.

    Every scanner is tracked (``scan_topic``: one topic or a list; by default every
    LaserScan topic, one of those that share a frame). ``fixed_frame`` is the frame to
    track in ('' for the scan frame); by default ``tf.fixed_frame`` where the bag's
    transforms (and the ``mounts``) link the scanners to it, else for several scanners
    the frame that links them, else the scan frame (:func:`choose_fixed_frame`; the
    summary says which and why).

    Raises
    ------
    BagError
        When the output exists, or the input is missing, broken, has no usable topic or
        no scans on it.
    PlotError
        When ``plot_path`` is a folder or not an image file name
        (:func:`imagefile.image_path`); checked before any scan is read.

    """
    out = Path(output_path)
    check_output(out)
    if plot_path:             # checked, its folder made: not found wanting after the run
        from ..report.imagefile import image_path

        plot_path = image_path(plot_path)
    frame, why, topics, notes = choose_fixed_frame(input_path, scan_topic, cfg, fixed_frame,
                                                   mounts)
    reader, conns = open_scans(input_path, scan_topic)   # a scanner's second topic too
    total = sum(c.msgcount for c in conns)
    reader.close()
    topic = ', '.join(sorted(topics))
    if total == 0:
        raise BagError(f'{topic} in {input_path} holds no scans: nothing to replay')
    summary = ReplaySummary(topic=topic, output=str(out), fixed_frame=frame, frame_why=why,
                            notes=notes,
                            removed_stages=[str(p) for p in remove_stale_stages(out)])
    tally = _Tally()
    sketch = None
    if plot_path:
        from ..report.plotting import RunSketch

        sketch = RunSketch(lambda e: shapes(e, cfg.extraction) == SHAPE_RECTANGLE)
    bar = _Progress(total) if progress else None
    try:
        transforms: list = []
        results = replay_results(input_path, cfg, scan_topic, summary.renamed_frames, frame,
                                 transforms, mounts, untracked=True)
        fov = _write_bag(out, results, cfg, tally, sketch, bar, transforms,
                         {f: t for t, f in topics.items()} if len(topics) > 1 else {})
    finally:
        if bar:
            bar.close()
    tally.summarise(summary)
    if sketch is not None:
        from ..report.plotting import plot_run

        plot_run(sketch, plot_path, title=f'{Path(input_path).name} {topic}: '
                 f'{summary.scans} scans, {summary.distinct_ids} ids', fov=fov)
        summary.plot = str(plot_path)
    return summary


def _write_bag(out: Path, results, cfg: TrackerConfig, tally: '_Tally', sketch, bar,
               transforms: list, topic_of: dict):
    """Write every scan and its tracks and markers into the MCAP bag ``out`` (staged, moved
    into place when complete), with the transform messages ``results`` put in
    ``transforms`` as it read them; count them in ``tally``. Each scanner's scans go on
    its topic of ``topic_of`` (by frame; ``/scan`` for a scanner not in it). Returns each
    scanner's field of view (by frame; '' in the scan frame)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = message_typestore()
    prev_ids: set = set()
    fov: dict = {}
    with staged_bag(out) as tmp, Writer(tmp, version=9,
                                        storage_plugin=StoragePlugin.MCAP) as writer:
        c_scans = {t: writer.add_connection(t, SCAN_TYPE, typestore=store)
                   for t in sorted(set(topic_of.values()) or {SCAN_TOPIC})}
        c_tracks = writer.add_connection(TRACKS_TOPIC, TRACKS_TYPE, typestore=store)
        c_markers = writer.add_connection(MARKERS_TOPIC, MARKERS_TYPE, typestore=store)
        c_tf = {}
        for k, (scan, res) in enumerate(results):
            _write_transforms(writer, store, c_tf, transforms)
            if isinstance(res, Untracked):      # a scanner's other topic: kept as read
                writer.write(_connection(writer, store, c_scans, res.topic), res.record_ns,
                             store.serialize_cdr(build_message(store, SCAN_TYPE,
                                                               scan_data(scan)), SCAN_TYPE))
                continue
            if res.event != 'malformed_scan' and (res.scanner or '') not in fov:
                fov[res.scanner or ''] = scan_fov(scan)
            tracks = build_message(store, TRACKS_TYPE, tracks_data(res, cfg))
            mdata, prev_ids = markers_data(res, cfg, prev_ids)
            markers = build_message(store, MARKERS_TYPE, mdata)
            c_scan = _connection(writer, store, c_scans,
                                 topic_of.get(getattr(scan.header, 'frame_id', ''), SCAN_TOPIC))
            writer.write(c_scan, res.stamp_ns, store.serialize_cdr(
                build_message(store, SCAN_TYPE, scan_data(scan)), SCAN_TYPE))
            writer.write(c_tracks, res.stamp_ns, store.serialize_cdr(tracks, TRACKS_TYPE))
            writer.write(c_markers, res.stamp_ns, store.serialize_cdr(markers, MARKERS_TYPE))
            tally.add(res)
            if sketch is not None:
                sketch.add(res)
            if bar:
                bar.update(k + 1)
        _write_transforms(writer, store, c_tf, transforms)
    return fov


def _connection(writer, store, connections: dict, topic: str):
    """The output's LaserScan connection on ``topic``, added the first time."""
    if topic not in connections:
        connections[topic] = writer.add_connection(topic, SCAN_TYPE, typestore=store)
    return connections[topic]


def _write_transforms(writer, store, connections: dict, transforms: list) -> None:
    """Write (and take out of ``transforms``) the transform messages read so far,
    ``/tf_static`` latched as ``ros2 bag play`` needs it for RViz."""
    for topic, record_ns, msg in transforms:
        topic = '/' + topic.lstrip('/')
        if topic not in connections:
            qos = _latched() if topic == '/tf_static' else ()
            connections[topic] = writer.add_connection(topic, TF_TYPE, typestore=store,
                                                       offered_qos_profiles=qos)
        data = build_message(store, TF_TYPE, tf_data(msg))
        writer.write(connections[topic], record_ns, store.serialize_cdr(data, TF_TYPE))
    transforms.clear()


def _latched():
    """Transient-local durability, as tf2's static broadcaster offers ``/tf_static``."""
    from rosbags.interfaces import (
        Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime,
    )

    never = QosTime(2147483647, 4294967295)
    return [Qos(QosHistory.KEEP_LAST, 1, QosReliability.RELIABLE,
                QosDurability.TRANSIENT_LOCAL, never, never, QosLiveliness.AUTOMATIC, never,
                False)]


class _Tally:
    """The figures of a replay, scan by scan: times, counts, events and how far each id
    travelled from where it was first reported."""

    def __init__(self):
        self.times, self.counts, self.detections = [], [], 0
        self.events, self.first_reasons = {}, {}
        self.travel = Travel()
        self.legs_from = None

    def add(self, res) -> None:
        self.times.append(res.processing_time)
        if self.legs_from is None and res.diagnostics.get('legs'):
            self.legs_from = len(self.times)
        self.counts.append(len(res.estimates))
        self.detections += res.diagnostics.get('detections', 0)
        if res.event:
            self.events[res.event] = self.events.get(res.event, 0) + 1
            if res.error:
                self.first_reasons.setdefault(res.event, res.error)
        self.travel.add(res.estimates)

    def summarise(self, summary: ReplaySummary) -> None:
        summary.scans = len(self.times)
        summary.valid_detections = self.detections
        summary.events.update(self.events)
        summary.first_reasons.update(self.first_reasons)
        summary.distinct_ids = self.travel.distinct()
        summary.moving_ids = self.travel.moved()
        summary.legs_from = self.legs_from
        if self.times:
            ms = np.asarray(self.times) * 1e3
            summary.median_ms = float(np.median(ms))
            summary.p99_ms = float(np.percentile(ms, 99))
            summary.mean_count = float(np.mean(self.counts))
            summary.max_count = int(np.max(self.counts))


def scan_fov(scan):
    a0 = float(scan.angle_min)
    a1 = a0 + float(scan.angle_increment) * (len(scan.ranges) - 1)
    rmax = float(scan.range_max)
    if not math.isfinite(rmax) or rmax <= 0:
        return None
    return min(a0, a1), max(a0, a1), rmax
