"""
A walker as a scanner at leg height sees it: two legs that swing in turn.

Each leg is a disc of ``LEG_RADIUS``, ``HIP`` either side of the walker's path. While
the walker moves, the legs swing fore and aft in opposite phase, ``CADENCE`` gait cycles a
second, each ``STRIDE_PER_SPEED`` times the speed ahead of and behind the centre (at
most ``MAX_SWING``); standing, they stand side by side. Walking across the beams, one
leg passes through the other's shadow twice a cycle.

The truth extent is the footprint of the two legs, as the scanner's returns spread:
``4 d d' + r^2 I`` with ``d`` half the vector from one leg to the other (the extent of an
ellipse of semi-axes a, b is diag(a^2, b^2) in its axes, a disc's r^2 I).
"""

from __future__ import annotations

import math

import numpy as np

LEG_RADIUS = 0.06          # m: a shin at 20-40 cm
HIP = 0.09                 # m: each leg's offset from the path
CADENCE = 0.9              # gait cycles a second
STRIDE_PER_SPEED = 0.25    # m of swing per m/s
MAX_SWING = 0.3            # m: the farthest a leg swings ahead of the centre
REACH = math.hypot(HIP, MAX_SWING) + LEG_RADIUS    # m: a circle round the centre holds both
LEG_EXTENT = LEG_RADIUS ** 2 * np.eye(2)           # one leg's extent (a disc)


def leg_offsets(heading: float, speed: float, t: float, phase: float) -> np.ndarray:
    """Half the vector from the second leg to the first (2,), at time ``t`` (s)."""
    swing = min(MAX_SWING, STRIDE_PER_SPEED * speed) * math.sin(
        2.0 * math.pi * CADENCE * t + phase)
    c, s = math.cos(heading), math.sin(heading)
    return np.array([swing * c - HIP * s, swing * s + HIP * c])


def leg_centres(centre, heading: float, speed: float, t: float, phase: float) -> np.ndarray:
    """The two legs' centres (2, 2) of a walker at ``centre``."""
    d = leg_offsets(heading, speed, t, phase)
    return np.array([centre + d, centre - d])


def legs_extent(heading: float, speed: float, t: float, phase: float) -> np.ndarray:
    """The truth extent (2, 2) of the two legs (see the module's notes)."""
    d = leg_offsets(heading, speed, t, phase)
    return 4.0 * np.outer(d, d) + LEG_EXTENT
