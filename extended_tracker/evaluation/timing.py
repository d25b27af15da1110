"""Timing helpers of the benchmark: machine line, yardstick, statistics, memory, growth."""

from __future__ import annotations

import os
import platform
import resource
import time

import numpy as np


def machine_line() -> str:
    """The CPU, its count, and the Python and numpy builds the figures come from."""
    cpu = platform.processor() or platform.machine()
    try:
        with open('/proc/cpuinfo') as fh:
            cpu = next((ln.split(':', 1)[1].strip() for ln in fh
                        if ln.startswith('model name')), cpu)
    except OSError:
        pass
    simd = np.show_config(mode='dicts').get('SIMD Extensions', {})
    found = ' '.join(simd.get('found', [])) or 'baseline only'
    import scipy

    return (f'machine: {cpu}, {os.cpu_count()} CPUs; Python {platform.python_version()}, '
            f'numpy {np.__version__} (SIMD {found}), scipy {scipy.__version__}')


def exp_ns(reps: int = 15, size: int = 4096) -> float:
    """
    Median ns per element of ``np.exp`` on float64: where numpy has no vectorised kernel
    for the CPU it calls the C library's scalar ``exp``, several times slower, and the
    filter's log-domain sums pay it (a few thousand elements a step).
    """
    x = np.linspace(-30.0, 0.0, size)
    out = np.empty(size)
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        np.exp(x, out=out)
        times.append(time.perf_counter() - t0)
    return float(np.median(times) / size * 1e9)


def reference_ms(reps: int = 15) -> float:
    """
    Median ms of a fixed workload: 1000 numpy operations on arrays of two dozen elements
    with the Python around them, the kind of work a filter step is made of. Its swings from
    minute to minute are the machine's, so it reads beside the step times.
    """
    a = np.linspace(-3.0, 3.0, 24)
    b = a[::-1].copy()
    idx = np.arange(0, 24, 2)
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        for _ in range(100):
            c = np.exp(a - b)
            s = np.add.reduce(c)     # the yardstick's fixed workload: never change it
            m = np.maximum(a, b)
            order = m.argsort()
            d = c[order] * s
            np.concatenate([d[idx], a[:3]])
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e3)


def timing_stats(seconds):
    ms = np.asarray(seconds) * 1e3
    return float(np.median(ms)), float(np.percentile(ms, 99)), float(np.max(ms))


def growth_exponent(x, y) -> float:
    """
    Least-squares slope of ``log y`` against ``log x``: ``y ~ x^k`` gives ``k`` (1 is
    linear growth, below 1 slower).
    """
    x = np.log(np.asarray(x, dtype=float))
    y = np.log(np.asarray(y, dtype=float))
    x = x - x.mean()
    return float(np.dot(x, y - y.mean()) / np.dot(x, x))


def _growth_cases(rows, fixed_ms: float):
    """Objects x cells, detections and the time above ``fixed_ms`` of the ``rows``
    (``(objects, detections, cells, median ms)``) with objects and a time above it, as
    arrays; None when fewer than two are left to fit."""
    used = [(n * c, d, t - fixed_ms) for n, d, c, t in rows if n > 0 and t > fixed_ms]
    if len(used) < 2:
        return None
    return tuple(np.array(a, dtype=float) for a in zip(*used))


def report_growth(rows, fixed_ms: float) -> tuple[float, float]:
    """
    How the filter step's cost grows: the exponent of its time above the fixed cost
    (the step on a scan with no returns and no tracks) against objects x cells and
    against detections, over ``rows`` of ``(objects, detections, cells, median ms)``
    (those with objects and a time above the fixed cost). Printed and returned.
    """
    cases = _growth_cases(rows, fixed_ms)
    if cases is None:
        print('growth: too few cases above the fixed cost to fit')
        return float('nan'), float('nan')
    oc, d, extra = cases
    k_oc = growth_exponent(oc, extra)
    k_d = growth_exponent(d, extra)
    print(f'growth of the filter step above its fixed cost ({fixed_ms:.2f} ms), {len(oc)} '
          f'cases: time ~ (objects x cells)^{k_oc:.2f} '
          f'(objects x cells {int(oc.min())}-{int(oc.max())}), '
          f'~ detections^{k_d:.2f} ({int(d.min())}-{int(d.max())}); 1 is linear')
    return k_oc, k_d


def peak_rss_mb():
    """The process's peak resident memory (MB): VmHWM, the high-water mark of VmRSS."""
    try:
        with open('/proc/self/status') as fh:
            for line in fh:
                if line.startswith('VmHWM:'):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def rss_mb():
    try:
        with open('/proc/self/statm') as fh:
            pages = int(fh.read().split()[1])
        return pages * resource.getpagesize() / 2**20
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
