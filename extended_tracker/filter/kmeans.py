"""k-means++ for sub-partitioning, with seeded generators reused per thread."""

from __future__ import annotations

import threading

import numpy as np

_THREAD = threading.local()      # generators are stateful: one set per thread


def seeded_generator(seed: int) -> np.random.Generator:
    """
    ``np.random.default_rng(seed)`` as new: a cached generator (per thread) put back to
    its seeded state; expanding a seed sequence costs tens of microseconds per k-means.
    """
    cache = getattr(_THREAD, 'generators', None)
    if cache is None:
        cache = _THREAD.generators = {}
    entry = cache.get(seed)
    if entry is None:
        gen = np.random.default_rng(seed)
        entry = cache[seed] = (gen, gen.bit_generator.state)
    entry[0].bit_generator.state = entry[1]
    return entry[0]


def kmeans_pp(points: np.ndarray, k: int, seed: int = 0, iters: int = 20,
              init: np.ndarray | None = None) -> np.ndarray:
    """
    Deterministic k-means (k-means++ seeding unless ``init`` centres are given).

    Returns the label of each point; empty clusters are dropped from the labels.
    """
    n = len(points)
    if k >= n:
        return np.arange(n)
    x, y = points[:, 0], points[:, 1]
    if init is None:
        rng = seeded_generator(seed)
        first = points[rng.integers(n)]
        centres = [first]
        dx, dy = x - first[0], y - first[1]
        d2 = dx * dx + dy * dy                                 # to the nearest centre so far
        for _ in range(1, k):
            total = np.sum(d2)
            if total <= 0:
                break
            # rng.choice(n, p=d2 / total) without its argument checks: the same cdf, the
            # same single uniform draw, the same index
            cdf = (d2 / total).cumsum()
            cdf /= cdf[-1]
            c = points[int(cdf.searchsorted(rng.random(), side='right'))]
            centres.append(c)
            dx, dy = x - c[0], y - c[1]
            np.minimum(d2, dx * dx + dy * dy, out=d2)
        centres = np.array(centres)
    else:
        centres = np.array(init, dtype=float)
    labels = np.zeros(n, dtype=np.int64)
    # squares as products (x ** 2 is x * x in numpy, bit for bit, but a Python operand
    # costs each call more than the arithmetic here); the centres' coordinates as arrays
    # of their own, not columns of a (k, 2) array rebuilt each iteration
    x_col, y_col = x[:, None], y[:, None]
    k = len(centres)
    cx, cy = centres[:, 0], centres[:, 1]
    for _ in range(iters):
        dx, dy = x_col - cx, y_col - cy
        new = (dx * dx + dy * dy).argmin(axis=1)
        if _ and (new == labels).all():
            break
        labels = new
        # each centre moves to the mean of its points; an empty cluster's centre stays
        count = np.bincount(labels, minlength=k)
        sx = np.bincount(labels, weights=x, minlength=k)
        sy = np.bincount(labels, weights=y, minlength=k)
        filled = count > 0
        if filled.all():
            cx, cy = sx / count, sy / count
        else:
            cx[filled] = sx[filled] / count[filled]
            cy[filled] = sy[filled] / count[filled]
    return labels
