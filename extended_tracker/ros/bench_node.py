"""Node overhead: the callback's total time against ``pipeline.step`` alone (in-process)."""

from __future__ import annotations

import os
import time

import numpy as np


def node_overhead(scans: int = 200, marker_listener: bool = False) -> dict:
    """
    Feed simulated scans straight into ``TrackerNode.on_scan``; time both. With
    ``marker_listener`` a second node subscribes to the markers first (as RViz would), so
    the node builds and publishes them.
    """
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.pop('ROS_LOCALHOST_ONLY', None)
    import rclpy
    from rclpy.context import Context
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import LaserScan

    from ..bag.bagio import scan_data
    from ..sim.laser import simulate, tutorial_scene
    from .convert import fill
    from .node import TrackerNode

    msgs = [fill(LaserScan(), scan_data(s)) for s, _ in simulate(tutorial_scene(),
                                                                   scans / 10.0, seed=9)]
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        node = TrackerNode(context=ctx,
                           parameter_overrides=[Parameter('background.enabled', value=False)])
        if node.transforms is not None and node.transforms.kind == 'own':
            # the scanner fixed in odom: each scan looks its transform up, as on a robot
            node.transforms.buffer.set_transform('odom', 'laser', 0, (0.0, 0.0, 0.0),
                                                 (0.0, 0.0, 0.0, 1.0), static=True)
        listener = None
        if marker_listener:
            from visualization_msgs.msg import MarkerArray

            listener = rclpy.create_node('marker_listener', context=ctx)
            listener.create_subscription(MarkerArray, 'tracks/markers', lambda m: None, 10)
            deadline = time.monotonic() + 5.0
            while (node.pub_markers.get_subscription_count() < 1
                   and time.monotonic() < deadline):
                time.sleep(0.01)
        total, inner = [], []
        import extended_tracker.pipeline as node_mod

        real_step = node_mod.step

        def timed_step(*args, **kwargs):
            t0 = time.perf_counter()
            out = real_step(*args, **kwargs)
            inner.append(time.perf_counter() - t0)
            return out

        node_mod.step = timed_step
        try:
            for m in msgs:
                t0 = time.perf_counter()
                node.on_scan(m)
                total.append(time.perf_counter() - t0)
        finally:
            node_mod.step = real_step
        node.destroy_node()
        if listener is not None:
            listener.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
    return overhead_figures(total, inner)


def overhead_figures(total, inner, warm: int = 20) -> dict:
    """
    The figures of :func:`node_overhead`, in ms, from the seconds of each callback
    (``total``) and of the ``step`` inside it (``inner``), after the first ``warm``: the
    medians of both, the median of each callback's own overhead (not the difference of
    the medians) and the callback's p99.
    """
    total = np.asarray(total[warm:], dtype=float) * 1e3
    inner = np.asarray(inner[warm:], dtype=float) * 1e3
    return {'callback_median_ms': float(np.median(total)),
            'step_median_ms': float(np.median(inner)),
            'overhead_median_ms': float(np.median(total - inner)),
            'callback_p99_ms': float(np.percentile(total, 99))}
