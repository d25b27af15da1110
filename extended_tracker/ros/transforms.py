"""
Transforms for the live node: tf2_ros where it is installed (a Jazzy install), else the
project's own :class:`frames.buffer.TransformBuffer` fed from ``/tf`` and ``/tf_static``
(this venv, where no tf2 wheel exists). Both give the node one call,
``lookup(target, source, stamp_ns) -> frames.buffer.Transform``, raising the project's
:class:`frames.buffer.TransformError` kinds.
"""

from __future__ import annotations

import numpy as np

from ..frames.buffer import ConnectivityError, ExtrapolationError, Transform, TransformBuffer


def transform_of(msg) -> Transform:
    """A geometry_msgs/Transform as a :class:`Transform`."""
    t, q = msg.translation, msg.rotation
    return Transform(np.array([t.x, t.y, t.z], float), np.array([q.x, q.y, q.z, q.w], float))


def tf2_lookup(tf2_ros, buffer):
    """The lookup through a tf2_ros ``Buffer``; tf2's exceptions mapped to the project's
    (an extrapolation into the future is one that waiting may cure)."""
    from rclpy.time import Time

    def lookup(target: str, source: str, stamp_ns: int) -> Transform:
        try:
            ts = buffer.lookup_transform(target, source, Time(nanoseconds=stamp_ns))
        except tf2_ros.ExtrapolationException as err:
            raise ExtrapolationError(str(err), 'future' in str(err)) from err
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException) as err:
            raise ConnectivityError(str(err)) from err
        return transform_of(ts.transform)

    return lookup


class TransformSource:
    """
    The node's transforms. ``kind`` says which: ``tf2_ros``, or ``own`` (the project's
    buffer fed by the node's subscriptions to ``/tf`` and ``/tf_static``).
    """

    def __init__(self, node, tf2_ros=None):
        if tf2_ros is None:
            try:
                import tf2_ros
            except ImportError:
                tf2_ros = None
        if tf2_ros is not None:
            self.kind = 'tf2_ros'
            self.buffer = tf2_ros.Buffer()
            self.listener = tf2_ros.TransformListener(self.buffer, node)
            self.lookup = tf2_lookup(tf2_ros, self.buffer)
            return
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from tf2_msgs.msg import TFMessage

        self.kind = 'own'
        self.buffer = TransformBuffer()
        self.lookup = self.buffer.lookup
        self.refused = 0                      # transforms refused (a zero quaternion, ...)
        self.messages = 0                     # TFMessages taken in
        latched = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.subscriptions = [
            node.create_subscription(TFMessage, '/tf', lambda m: self.feed(m, False),
                                     QoSProfile(depth=100)),
            node.create_subscription(TFMessage, '/tf_static', lambda m: self.feed(m, True),
                                     latched)]

    def add_mount(self, parent: str, child: str, pose) -> None:
        """A static planar transform ``parent -> child`` given to the node (a scanner's
        mount from its parameters), as if published on ``/tf_static``."""
        q = pose.quaternion
        if self.kind == 'own':
            self.buffer.set_transform(parent, child, 0, (pose.x, pose.y, 0.0), q, static=True)
            return
        from geometry_msgs.msg import TransformStamped

        ts = TransformStamped()
        ts.header.frame_id, ts.child_frame_id = parent, child
        ts.transform.translation.x, ts.transform.translation.y = pose.x, pose.y
        (ts.transform.rotation.x, ts.transform.rotation.y, ts.transform.rotation.z,
         ts.transform.rotation.w) = q
        self.buffer.set_transform_static(ts, 'extended_tracker mounts')

    def feed(self, msg, static: bool) -> None:
        """Add a TFMessage's transforms to the own buffer."""
        self.messages += 1
        for ts in msg.transforms:
            stamp = int(ts.header.stamp.sec) * 1_000_000_000 + int(ts.header.stamp.nanosec)
            tf = transform_of(ts.transform)
            try:
                self.buffer.set_transform(ts.header.frame_id, ts.child_frame_id, stamp,
                                          tf.translation, tf.quaternion, static)
            except ValueError:
                self.refused += 1


__all__ = ['TransformSource', 'tf2_lookup', 'transform_of']
