"""
Synthetic detections drawn from the filter's own measurement model (no laser).

Each object is a moving ellipse; per scan it yields ``Poisson(rate)`` points from
``N(centre, rho X + R)`` (or none when missed), plus Poisson clutter uniform in a box.
Used by the filter-core scenario tests and benchmarks; the laser simulator lives in
:mod:`extended_tracker.sim.laser`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PointObject:
    """A constant-velocity ellipse: start (m), velocity (m/s), extent X (m^2), rate."""

    start: tuple
    velocity: tuple
    extent: tuple = ((0.09, 0.0), (0.0, 0.09))
    rate: float = 12.0
    t_start: float = 0.0
    t_end: float = np.inf

    def centre(self, t: float) -> np.ndarray:
        start = np.asarray(self.start, float)
        return start + np.asarray(self.velocity, float) * (t - self.t_start)

    def alive(self, t: float) -> bool:
        return self.t_start <= t <= self.t_end


def point_scene(objects, t, rng, rho=0.25, sigma=0.03, clutter_rate=1.0,
                box=((-10.0, -10.0), (10.0, 10.0)), missed=()):
    """
    Detections at time ``t`` and the truth.

    Returns
    -------
    points : (m, 2) array
    truth : list of (index, centre) of the objects alive at ``t``
    """
    pts = []
    truth = []
    R = sigma ** 2 * np.eye(2)
    for i, ob in enumerate(objects):
        if not ob.alive(t):
            continue
        c = ob.centre(t)
        truth.append((i, c))
        if i in missed:
            continue
        n = rng.poisson(ob.rate)
        if n:
            pts.append(rng.multivariate_normal(c, rho * np.asarray(ob.extent) + R, size=n))
    lo, hi = np.asarray(box[0]), np.asarray(box[1])
    n_c = rng.poisson(clutter_rate)
    if n_c:
        pts.append(rng.uniform(lo, hi, size=(n_c, 2)))
    points = np.vstack(pts) if pts else np.zeros((0, 2))
    return points, truth
