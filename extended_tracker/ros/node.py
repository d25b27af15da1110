"""
The live node: ``ros2 run extended_tracker tracker_node``.

Subscribes to ``scan`` (sensor_msgs/LaserScan, sensor-data QoS, remappable) and, for
every scan, publishes ``tracks`` (extended_tracker_msgs/ExtendedObjectArray),
``tracks/markers`` (visualization_msgs/MarkerArray; only while it has a subscriber) and
``tracks/diagnostics`` (diagnostic_msgs/DiagnosticArray), all stamped with the scan's
stamp, in the fixed frame ``tf.fixed_frame`` (odom) where the transforms link the scan
to it, else in the scan frame (said once: a stationary scanner with no TF). Transforms
come from tf2_ros where installed, else from ``/tf`` and ``/tf_static``
(:mod:`ros.transforms`); a scan waits up to ``tf.timeout`` for its own
(:mod:`frames.placing`). The service ``~/reset`` (std_srvs/Trigger) drops the tracks, the learned
background and the frame lock (a moved scanner); ids continue. A thin
shell around :func:`extended_tracker.pipeline.step`, the same function the bag replay
calls.
"""

from __future__ import annotations

import math
import sys
import threading
import time

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from extended_tracker_msgs.msg import ExtendedObjectArray
from rcl_interfaces.msg import SetParametersResult
import rclpy
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import (
    InvalidParameterTypeException, InvalidParameterValueException, ParameterUninitializedException,
)
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data, QoSProfile
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import LaserScan
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from .. import stopping
from ..config import from_flat, to_flat, TrackerConfig
from ..configio import NODE_NAME
from ..errors import ConfigError
from ..filter.clutter import clutter_rate_in_use
from ..frames.placing import NOTICES, PLACING_EVENTS, ScanPlacer
from ..pipeline import held, PipelineState, reset, step_placed
from ..report.messages import markers_data, tracks_data
from .convert import fill
from .entry import take_signals
from .events import EventLog, Pace, ScanGaps
from .parameters import (
    declare_scanner_parameters, parameter_descriptors, parse_mounts, range_error, type_error,
    unknown_overrides,
)
from .transforms import TransformSource

# the node's own events. A bug: the pipeline raised on a scan (answered with the previous
# estimates), or building or publishing its messages did.
INTERNAL_ERROR = 'internal_error'
# FALLING_BEHIND_SCANS scans in a row whose callback took longer than the time from the
# previous scan's stamp to theirs: scans queue up, and the sensor-data QoS drops them
FALLING_BEHIND = 'falling_behind'
FALLING_BEHIND_SCANS = 10
# scans missing between the stamps of those that reach the callback (ros.events.ScanGaps)
SCANS_DROPPED = 'scans_dropped'
NODE_EVENTS = (INTERNAL_ERROR, FALLING_BEHIND, SCANS_DROPPED) + PLACING_EVENTS
#: how often what was counted and not logged is summarised in the log, s
SUMMARY_PERIOD_S = 10.0
#: how often the queue of scans waiting for their transform is looked at, s
DRAIN_PERIOD_S = 0.02
class TrackerNode(Node):
    """Extended object tracker on the LaserScan topics of one or more scanners."""

    def __init__(self, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self._declare_parameters()
        self.cfg = self._read_config()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.state = PipelineState.initial(self.cfg)
        self.marker_ids: set = set()
        self.events = EventLog()
        self.gaps: dict = {}                      # scanner frame -> its ScanGaps
        self.counts = self.events.counts          # event -> count (the diagnostics' count_*)
        self.unknown_parameters = self._check_overrides()
        self.scans = 0
        self.pace = Pace(FALLING_BEHIND_SCANS)
        self.legs_said = False                    # the log said the scans show legs
        reliable = QoSProfile(depth=10)
        self.pub_tracks = self.create_publisher(ExtendedObjectArray, 'tracks', reliable)
        self.pub_markers = self.create_publisher(MarkerArray, 'tracks/markers', reliable)
        self.pub_diag = self.create_publisher(DiagnosticArray, 'tracks/diagnostics', reliable)
        self.subs = [self.create_subscription(LaserScan, topic, self.on_scan,
                                              qos_profile_sensor_data)
                     for topic in self.get_parameter('scan_topics').value]
        self.sub = self.subs[0]
        self.srv_reset = self.create_service(Trigger, '~/reset', self._on_reset)
        # on the steady clock: the summary comes on time whatever the ROS clock does
        self.summary_timer = self.create_timer(
            SUMMARY_PERIOD_S, self.log_summary, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f'tracking {", ".join(s.topic_name for s in self.subs)} in '
            f'{self.cfg.model.mode} mode, p_D '
            f'{self.cfg.detection.model}, clutter density {self.cfg.model.clutter_density}, '
            f'background {"on" if self.cfg.background.enabled else "off"}')
        self.frame_note = 'the scan frame (tf.fixed_frame is empty)'
        self.transforms, self.placer = self._transforms()

    def _transforms(self):
        """The transform source and the scans' queue, or none with ``tf.fixed_frame``
        empty (tracking in the scan frame)."""
        tf = self.cfg.tf
        if not tf.fixed_frame:
            return None, None
        source = TransformSource(self)
        given = self.get_parameter('mounts').value or []
        for parent, child, pose in parse_mounts(given):
            source.add_mount(parent, child, pose)
        placer = ScanPlacer(source.lookup, tf.fixed_frame, tf.timeout, tf.max_tilt,
                            self.cfg.timing.latency, self.cfg.timing.max_gap)
        self.drain_timer = self.create_timer(DRAIN_PERIOD_S, self.drain)
        self.frame_note = f'{tf.fixed_frame} (transforms from {source.kind})'
        self.get_logger().info(f'tracking in {tf.fixed_frame} where the transforms link the '
                               f'scans to it (from {source.kind}; a scan waits up to '
                               f'{tf.timeout:g} s for its own)')
        return source, placer

    # --- parameters ---
    def _declare_parameters(self) -> None:
        """
        Declare ``scan_topics`` (the node's own: the LaserScan topics of the scanners to
        track, ``[scan]`` by default, so that ``-r scan:=...`` keeps working) and every
        configuration field with its descriptor. A value the descriptor refuses (a wrong
        type, or out of range, from a parameter file or ``-p``) is a ConfigError in one
        line with the fix, not rclpy's traceback. An array given no value is set to the
        empty array, so that GetParameters answers for it: rclpy's service answers
        nothing at all when one name asked for is uninitialised.
        """
        declare_scanner_parameters(self)
        for name, (default, desc) in parameter_descriptors().items():
            try:
                if isinstance(default, list):
                    self.declare_parameter(name, rclpy.Parameter.Type.DOUBLE_ARRAY, desc)
                    if self.get_parameter_or(name).value is None:
                        self.set_parameters([rclpy.Parameter(
                            name, rclpy.Parameter.Type.DOUBLE_ARRAY, list(default))])
                else:
                    self.declare_parameter(name, default, desc)
            except InvalidParameterTypeException as err:
                raise ConfigError(type_error(name, desc.type, err)) from err
            except InvalidParameterValueException as err:
                raise ConfigError(range_error(name, desc, self._given(name))) from err

    def _given(self, name: str):
        """The value given for ``name`` (a parameter file, ``-p``), or None."""
        given = getattr(self, '_parameter_overrides', {}).get(name)
        return None if given is None else given.value

    def _read_config(self) -> TrackerConfig:
        flat = {}
        for name, default in to_flat(TrackerConfig()).items():
            try:
                value = self.get_parameter(name).value
            except ParameterUninitializedException:      # an array declared without value
                value = None
            flat[name] = list(value) if isinstance(default, list) and value is not None else (
                default if value is None else value)
        return from_flat(flat)           # raises ConfigError with the reason

    def _check_overrides(self) -> list:
        """Names given to the node that it does not have, said once at start-up with the
        nearest known name (:func:`parameters.unknown_overrides`)."""
        unknown, said = unknown_overrides(self)
        if unknown:
            self.counts['unknown_parameter'] = 1                  # in the diagnostics
            self.get_logger().warning(f'{len(unknown)} given parameter(s) this node does not '
                                      f'have, ignored: {", ".join(said)}')
        return unknown

    def _on_set_parameters(self, params) -> SetParametersResult:
        flat = to_flat(self.cfg)
        for p in params:
            if p.name == 'mounts' and self.transforms is not None:
                return SetParametersResult(successful=False, reason=(
                    'mounts is read at start-up: restart the node to change it'))
            if p.name not in flat:
                continue
            if p.name.startswith('tf.') and p.value != flat[p.name]:
                # the transform source and the scans' queue are made at start-up
                return SetParametersResult(successful=False, reason=(
                    f'{p.name} is read at start-up: restart the node to change it'))
            flat[p.name] = list(p.value) if isinstance(flat[p.name], list) else p.value
        try:
            new_cfg = from_flat(flat)
        except ConfigError as err:
            return SetParametersResult(successful=False, reason=str(err))
        self.cfg = new_cfg
        return SetParametersResult(successful=True)

    # --- the callbacks ---
    def on_scan(self, msg: LaserScan) -> None:
        """A scan: tracked now in the scan frame (``tf.fixed_frame`` empty, or a header the
        pipeline will call malformed), else queued for its transform."""
        # the arrival time stands in for a zero header stamp (event zero_stamp)
        arrival = self.get_clock().now().nanoseconds
        frame = getattr(getattr(msg, 'header', None), 'frame_id', None)
        if self.placer is None or not isinstance(frame, str):
            self.track(msg, arrival, None)
            return
        stamp = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
        self.placer.push(msg, stamp or arrival, frame, arrival)
        self.drain()

    def drain(self) -> None:
        """Track the queued scans whose transform came or whose wait is over (the
        timer calls it too, so a scan never waits past ``tf.timeout`` for the next one)."""
        if self.placer is None:
            return
        for placed in self.placer.ready(self.get_clock().now().nanoseconds):
            if placed.event in NOTICES:          # which frame: said once, in diagnostics
                self.frame_note = placed.error
                self.get_logger().info(placed.error)
            self.track(placed.scan, placed.arrival_ns, placed)

    def track(self, msg, arrival: int, placed) -> None:
        """One scan through the pipeline (placed in the fixed frame when ``placed``),
        then its publications."""
        t0 = time.perf_counter()
        try:
            self.state, result = step_placed(self.state, msg, self.cfg, arrival, placed)
        except Exception as err:
            # a bug must not take the node down, nor leave the scan unanswered: say it
            # loudly, and publish the previous estimates for it (the state is unchanged)
            text = f'pipeline failed on a scan: {err!r}'
            self._count(INTERNAL_ERROR, text, error=True)
            result = held(self.state, msg, INTERNAL_ERROR, text, arrival)
        self.scans += 1
        self._check_gap(msg)
        if self.state.legs.seen and not self.legs_said:
            self.legs_said = True
            self.get_logger().info(
                f'the scans show legs (scan {self.scans}): the scanner is at leg height, and '
                f'a walker\'s legs are one object from now on (partition.leg_gap '
                f'{self.cfg.partition.leg_gap:g} m)')
        if result.event and result.event != INTERNAL_ERROR:
            self._count(result.event, result.error or result.event.replace('_', ' '))
        try:
            self.pub_tracks.publish(fill(ExtendedObjectArray(), tracks_data(result, self.cfg)))
            # markers only while something listens (RViz, a recorder): building and
            # publishing them costs about half as much again as the tracking step. The ids
            # last drawn stay remembered, so a listener that returns gets the deletions.
            if self.pub_markers.get_subscription_count() > 0:
                mdata, self.marker_ids = markers_data(result, self.cfg, self.marker_ids)
                self.pub_markers.publish(fill(MarkerArray(), mdata))
        except Exception as err:           # an exception out of a callback ends spin
            self._count(INTERNAL_ERROR, f'publishing the estimates failed: {err!r}',
                        error=True)
        self.check_pace(result.stamp_ns, time.perf_counter() - t0)
        self.pub_diag.publish(self._diagnostics(result))

    def _check_gap(self, msg) -> None:
        """Count the scans that never reached the callback (event ``scans_dropped``), from
        the scanner's own stamps (a zero stamp, or an unreadable one, says nothing)."""
        try:
            stamp_ns = int(msg.header.stamp.sec) * 1_000_000_000 + int(msg.header.stamp.nanosec)
            scan_time = float(msg.scan_time)
        except (AttributeError, TypeError, ValueError):
            return
        if stamp_ns <= 0:
            return
        gaps = self.gaps.setdefault(getattr(msg.header, 'frame_id', ''), ScanGaps())
        missing = gaps.missing(stamp_ns, scan_time if math.isfinite(scan_time) else 0.0)
        if missing:
            self._count(SCANS_DROPPED, f'{missing} scan(s) missing before the one stamped '
                        f'{stamp_ns * 1e-9:.3f} s ({self.gaps_total()} in all): the '
                        f'subscription queue dropped them while the node was busy, or the '
                        f'driver never sent them')

    def gaps_total(self) -> int:
        """Scans missing between stamps, over every scanner."""
        return sum(g.total for g in self.gaps.values())

    def check_pace(self, stamp_ns: int, took: float) -> None:
        """Count (and say) FALLING_BEHIND_SCANS scans in a row that took longer than the
        scanner's period, as the stamps give it: the node is not keeping up."""
        period = self.pace.falling_behind(stamp_ns, took)
        if period is not None:
            self._count(FALLING_BEHIND, f'{FALLING_BEHIND_SCANS} scans in a row took longer '
                        f'than the scan period (the last {took * 1e3:.1f} ms against '
                        f'{period * 1e3:.1f} ms): scans queue up and the sensor-data QoS '
                        f'drops them')

    def _on_reset(self, request, response):
        self.state = reset(self.state, self.cfg)
        self.legs_said = False
        response.success = True
        response.message = (f'tracks, learned background and frame dropped; new ids start '
                            f'at {self.state.filter.next_label}')
        self.get_logger().info(f'reset: {response.message}')
        return response

    def summary(self) -> str:
        """One line for the log at exit: scans handled and the events met."""
        events = ', '.join(f'{k} {v}' for k, v in sorted(self.counts.items())) or 'none'
        missing = (f' ({self.gaps_total()} more never reached it)' if self.gaps_total()
                   else '')
        return f'stopping after {self.scans} scans{missing}; events: {events}'

    def _count(self, kind: str, text: str, error: bool = False) -> None:
        """Count an event; log it now if it is the first of its kind of reason."""
        line = self.events.record(kind, text)
        # one severity per call site: rclpy's logger refuses a site whose severity changes
        if line is not None and error:
            self.get_logger().error(line)
        elif line is not None:
            self.get_logger().warning(line)

    def log_summary(self) -> None:
        """Say what was counted since the last summary and not logged (the timer calls it
        every ``SUMMARY_PERIOD_S``)."""
        for line in self.events.summary_lines():
            self.get_logger().warning(line)

    def _diagnostics(self, result) -> DiagnosticArray:
        arr = DiagnosticArray()
        arr.header.stamp.sec = int(result.stamp_ns // 1_000_000_000)
        arr.header.stamp.nanosec = int(result.stamp_ns % 1_000_000_000)
        arr.header.frame_id = result.frame_id
        st = DiagnosticStatus()
        st.name = f'{self.get_name()}: tracker'
        st.hardware_id = result.frame_id
        st.level = (DiagnosticStatus.ERROR if result.event == INTERNAL_ERROR else
                    DiagnosticStatus.WARN if result.event else DiagnosticStatus.OK)
        st.message = result.event or 'ok'
        values = dict(result.diagnostics)
        values['processing_time_ms'] = round(result.processing_time * 1e3, 3)
        values['objects'] = len(result.estimates)
        values['scans'] = self.scans
        values['scans_dropped'] = self.gaps_total()
        values['clutter_rate'] = round(clutter_rate_in_use(self.state.filter, self.cfg), 2)
        values['reason'] = result.error or ''
        values['frame'] = self.frame_note
        for k, v in sorted(self.counts.items()):
            values[f'count_{k}'] = v
            values[f'last_reason_{k}'] = self.events.last_reason.get(k, '')
        st.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
        arr.status = [st]
        return arr


#: how often the spin loop looks for a stop request (a signal), s
STOP_POLL_S = 0.1

USAGE = f"""usage: tracker_node [--ros-args [-p NAME:=VALUE] [--params-file FILE] [-r scan:=TOPIC] ...]

Tracks pedestrians, bicycles and cars in a sensor_msgs/LaserScan topic with a GGIW-CPHD
filter (the extended_tracker package).

  subscribes  scan (sensor_msgs/LaserScan), or the topics of -p scan_topics:=[a, b];
              /tf and /tf_static (tf2_msgs/TFMessage)
  publishes   tracks (extended_tracker_msgs/ExtendedObjectArray)
              tracks/markers (visualization_msgs/MarkerArray)
              tracks/diagnostics (diagnostic_msgs/DiagnosticArray)
  service     ~/reset (std_srvs/Trigger): drop the tracks and the learned background

Every parameter, with its unit and range, is in the package's config/tracker.yaml
(ros2 param describe /{NODE_NAME} NAME on a running node). Node options go after
--ros-args; the node takes no others."""


def _program_arguments(args) -> list:
    """The command-line arguments that are not ROS's (not after ``--ros-args``), without
    the program name."""
    from rclpy.utilities import remove_ros_args

    return remove_ros_args(sys.argv if args is None else args)[1:]


def _refuse_start(message: str, err: BaseException | None = None) -> None:
    """One fatal line and status 2: a start the command line or the parameters refuse."""
    rclpy.logging.get_logger(NODE_NAME).fatal(message)
    raise SystemExit(2) from err


def main(args=None, stop: threading.Event | None = None) -> None:
    """
    Run the node until SIGINT or SIGTERM (or until ``stop`` is set: the executable's
    :mod:`entry` passes the event its signal handlers set). The signals only ask the spin
    loop to stop (rclpy's own handlers are off): the node then logs what it handled, with
    its context still up, and shuts down. rclpy's handlers shut the context down from
    their own thread at once, which raced with the node's last log line and its clean-up.
    """
    previous = None
    if stop is None:
        stop = threading.Event()
        previous = take_signals(stop)
    node = None
    try:
        if stop.is_set():                     # asked to stop while starting: nothing to do
            return
        try:
            extra = _program_arguments(args)
            if '-h' in extra or '--help' in extra:
                print(USAGE)
                return
            if extra:
                # `tracker_node -p model.mode:=phd` (no --ros-args): rclpy would ignore
                # the option and run on the defaults without a word
                _refuse_start(f'unexpected arguments {" ".join(extra)!r}: node options go '
                              'after --ros-args (tracker_node --ros-args -p NAME:=VALUE); '
                              'tracker_node --help lists what the node takes')
            rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        except _rclpy.RCLError as err:
            # a params file that cannot be read or parsed, a malformed remap: rcl's
            # reason, in one line instead of a traceback from rclpy.init
            _refuse_start(f'cannot start: {err}', err)
        executor = SingleThreadedExecutor()
        node = TrackerNode()
        executor.add_node(node)
        while not stop.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=STOP_POLL_S)
    except ExternalShutdownException:
        pass
    except ConfigError as err:
        _refuse_start(f'invalid configuration: {err}', err)
    finally:
        if node is not None:
            node.get_logger().info(node.summary())
            node.destroy_node()
        shutdown_context()
        stopping.give_back(previous)


def shutdown_context() -> None:
    """
    Shut the context down unless something else already has. ``try_shutdown`` checks
    and then shuts down; a shutdown from another thread between the two (as rclpy's own
    signal handlers did, 2 of 40 SIGINTs in a loop, before :func:`main` took the signals
    over) made it raise ``rcl_shutdown already called`` and the process exit 1.
    """
    try:
        rclpy.try_shutdown()
    except Exception:
        if rclpy.ok():
            raise


__all__ = ['TrackerNode', 'main', 'parameter_descriptors', 'NODE_EVENTS']
