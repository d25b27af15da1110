"""
Scenes at leg height: the suite's scenes with every walker drawn as two swinging legs,
and people walking past a stationary scanner, one to fifteen of them, some side by side.
"""

from __future__ import annotations

from dataclasses import replace
import math

import numpy as np

from .laser import _gap_times, LaserSpec, Scene, SimObject

# walkers of the body-height scenes: ellipses no wider than this (cars and bicycles stay)
WALKER_SEMI_AXIS = 0.4         # m
PHASE_STEP = 2.4               # rad between the gait phases of successive walkers

# the people-counting scanner: 180 deg, 0.35 deg, 10 m, at leg height
COUNTING_LASER = LaserSpec(n_beams=513, range_max=10.0)
COUNTING_SECONDS = 24.0
COMPANION_GAP = 0.6            # m between the paths of two people walking side by side
MIN_GAP = 0.9                  # m: people apart come no nearer than this (centres)


def at_leg_height(scenes):
    """The scene (or list of scenes, one per scanner) with each walker as two legs."""
    if isinstance(scenes, list):
        return [at_leg_height(s) for s in scenes]
    objects = tuple(
        replace(ob, shape='legs', gait_phase=PHASE_STEP * k)
        if ob.shape == 'ellipse' and max(ob.a, ob.b) <= WALKER_SEMI_AXIS else ob
        for k, ob in enumerate(scenes.objects))
    return replace(scenes, objects=objects)


def counting_scene(n: int, seed: int = 0) -> Scene:
    """
    ``n`` people walking past a stationary 180 deg scanner at leg height, across its view
    (along y, 1.5-6 m in front of it) one way or the other, entering over the first 12 s;
    about one in three walks beside a companion, ``COMPANION_GAP`` apart. No two people
    who do not walk together come nearer than ``MIN_GAP`` (drawn again until they do not).
    """
    rng = np.random.default_rng(seed)
    times = _gap_times(COUNTING_SECONDS)
    people, paths = [], []
    while len(people) < n:
        pair = len(people) + 2 <= n and rng.random() < 0.35
        x = rng.uniform(1.5, 6.0 - COMPANION_GAP)
        way = rng.choice([-1.0, 1.0])
        speed, t0 = rng.uniform(0.8, 1.4), rng.uniform(0.0, 12.0)
        walkers = [SimObject((x + COMPANION_GAP * j, -7.5 * way), (0.0, speed * way),
                             shape='legs', t_start=t0, t_end=t0 + 15.0 / speed,
                             gait_phase=rng.uniform(0.0, 2 * math.pi), kind='person')
                   for j in range(2 if pair else 1)]
        tracks = [w.centres(times) for w in walkers]
        if any(_too_near(a, b) for a in tracks for b in paths):
            continue
        people += walkers
        paths += tracks
    return Scene(objects=tuple(people), laser=COUNTING_LASER)


def _too_near(a: np.ndarray, b: np.ndarray) -> bool:
    d = np.linalg.norm(a - b, axis=1)
    return bool(np.isfinite(d).any() and np.nanmin(d) < MIN_GAP)


__all__ = ['at_leg_height', 'counting_scene', 'COUNTING_SECONDS']
