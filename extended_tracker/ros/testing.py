"""
The node under test, launch-free: a :class:`TrackerNode` and a probe node in one
process, on a private ``Context``, spun by a ``SingleThreadedExecutor`` in bounded steps.
The package's own node tests use it, and so can a robot's integration tests::

    from extended_tracker.ros.testing import NodeHarness

    with NodeHarness({'background.enabled': False}) as h:
        reply = h.send(scan)                   # the node's ExtendedObjectArray for it
        print([(o.id, o.position.x, o.position.y) for o in reply.objects])

``scan`` is a ``sensor_msgs/LaserScan`` or anything shaped like one (a bag's message read
with ``rosbags``, the simulator's scans). Every wait is bounded: a reply that does not
come within ``spin_limit`` seconds raises ``AssertionError``.

DDS: the harness sets ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` when the variable is
unset (a test's topics stay on the machine; the default multicasts to the network). A
test run beside a live robot graph on the same machine should also have a
``ROS_DOMAIN_ID`` of its own, as the package's ``test/conftest.py`` sets.
"""

from __future__ import annotations

import os
import time

from diagnostic_msgs.msg import DiagnosticArray
from extended_tracker_msgs.msg import ExtendedObjectArray
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan
from visualization_msgs.msg import MarkerArray

from ..bag.bagio import scan_data
from ..frames.pose import Pose2
from .convert import fill
from .node import TrackerNode

SPIN_LIMIT_S = 5.0          # per awaited message; loopback delivery takes milliseconds


def laser_scan(scan):
    """A ``sensor_msgs/LaserScan`` of any LaserScan-shaped object (returned as is if it
    is one)."""
    return scan if isinstance(scan, LaserScan) else fill(LaserScan(), scan_data(scan))


class NodeHarness:
    """
    A TrackerNode and a probe that publishes scans on ``scan`` and records ``tracks``,
    ``tracks/diagnostics`` (and, with ``markers``, ``tracks/markers``) in
    :attr:`tracks`, :attr:`diagnostics` and :attr:`markers`.

    Parameters
    ----------
    parameters : dict, optional
        ``{dotted_name: value}`` given to the node as parameter overrides.
    args : list of str, optional
        Command-line arguments for the context (``['--ros-args', '--params-file', path]``).
    markers : bool
        Subscribe to the markers at once (the node builds them only while someone
        listens); :meth:`watch_markers` does it later.
    spin_limit : float
        Seconds to wait for each awaited message or condition.

    Raises
    ------
    Whatever the node raises at start-up (an invalid parameter value), after the
    harness's context is shut down.
    """

    def __init__(self, parameters: dict | None = None, args=None, markers: bool = True,
                 spin_limit: float = SPIN_LIMIT_S):
        os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
        self.spin_limit = spin_limit
        self.ctx = Context()
        rclpy.init(context=self.ctx, args=args)
        overrides = [Parameter(k, value=v) for k, v in (parameters or {}).items()]
        try:
            self.node = TrackerNode(context=self.ctx, parameter_overrides=overrides)
        except BaseException:
            rclpy.try_shutdown(context=self.ctx)
            raise
        self.probe = rclpy.create_node('probe', context=self.ctx)
        self.tracks, self.markers, self.diagnostics = [], [], []
        self.probe.create_subscription(ExtendedObjectArray, 'tracks', self.tracks.append, 50)
        self.probe.create_subscription(DiagnosticArray, 'tracks/diagnostics',
                                       self.diagnostics.append, 50)
        self.pub = self.probe.create_publisher(LaserScan, 'scan', qos_profile_sensor_data)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self.executor.add_node(self.probe)
        self.expect_markers = False
        self._tf_pubs: dict = {}
        self.spin_until(lambda: self.pub.get_subscription_count() >= 1
                        and self.node.pub_diag.get_subscription_count() >= 1)
        if markers:
            self.watch_markers()

    def spin_until(self, done, limit: float | None = None) -> bool:
        """Spin both nodes until ``done()`` is true or ``limit`` seconds (default
        ``spin_limit``) pass; returns ``done()``."""
        deadline = time.monotonic() + (self.spin_limit if limit is None else limit)
        while not done() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.01)
        return bool(done())

    def watch_markers(self) -> None:
        """Subscribe the probe to the markers, wait until the node sees the subscription,
        and expect markers with every reply from now on."""
        self.probe.create_subscription(MarkerArray, 'tracks/markers', self.markers.append, 50)
        self.spin_until(lambda: self.node.pub_markers.get_subscription_count() >= 1)
        self.expect_markers = True

    def send(self, scan):
        """Publish one scan and return the node's ``tracks`` reply to it (its diagnostics
        and, when watched, its markers are in :attr:`diagnostics` and :attr:`markers`)."""
        n, n_diag, n_markers = len(self.tracks), len(self.diagnostics), len(self.markers)
        self.pub.publish(laser_scan(scan))
        if not self.spin_until(lambda: len(self.tracks) > n and len(self.diagnostics) > n_diag
                               and (not self.expect_markers or len(self.markers) > n_markers)):
            raise AssertionError(f'no reply from the node within {self.spin_limit} s')
        return self.tracks[-1]

    def send_transform(self, parent: str, child: str, x: float, y: float, yaw: float,
                       stamp_ns: int = 0, static: bool = False) -> None:
        """
        Publish a planar transform ``parent -> child`` on ``/tf`` (``/tf_static`` when
        ``static``, latched) and spin until the node has taken it in (its own buffer;
        with tf2_ros, a short spin).
        """
        from geometry_msgs.msg import TransformStamped
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from tf2_msgs.msg import TFMessage

        topic = '/tf_static' if static else '/tf'
        if topic not in self._tf_pubs:
            qos = QoSProfile(depth=100, durability=(DurabilityPolicy.TRANSIENT_LOCAL if static
                                                    else DurabilityPolicy.VOLATILE))
            self._tf_pubs[topic] = self.probe.create_publisher(TFMessage, topic, qos)
            self.spin_until(lambda: self._tf_pubs[topic].get_subscription_count() >= 1)
        ts = TransformStamped()
        ts.header.stamp.sec, ts.header.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        ts.header.frame_id, ts.child_frame_id = parent, child
        ts.transform.translation.x, ts.transform.translation.y = float(x), float(y)
        _, _, ts.transform.rotation.z, ts.transform.rotation.w = Pose2(yaw=yaw).quaternion
        source = self.node.transforms
        before = getattr(source, 'messages', 0)
        self._tf_pubs[topic].publish(TFMessage(transforms=[ts]))
        if source is not None and source.kind == 'own':
            self.spin_until(lambda: source.messages > before)
        else:
            self.spin_until(lambda: False, limit=0.05)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.probe.destroy_node()
        rclpy.try_shutdown(context=self.ctx)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


__all__ = ['NodeHarness', 'laser_scan', 'SPIN_LIMIT_S']
