"""
Walkers at leg height (``sim.legs``) and the people-counting scenes: geometry checked
against sampling and against the ray caster's own returns.
"""

import math

import numpy as np
import pytest

from extended_tracker.sim import legs
from extended_tracker.sim.laser import LaserSpec, Scene, SimObject, simulate
from extended_tracker.sim.leg_scenes import (
    at_leg_height, COMPANION_GAP, counting_scene, COUNTING_SECONDS, MIN_GAP,
)


def test_the_truth_extent_is_four_times_the_covariance_of_the_two_legs():
    """Monte Carlo: points spread uniformly over both leg discs have covariance a quarter
    of :func:`legs_extent` (an ellipse's extent is 4 times its area's covariance)."""
    rng = np.random.default_rng(3)
    heading, speed, t, phase = 0.7, 1.2, 0.31, 1.1
    centres = legs.leg_centres(np.zeros(2), heading, speed, t, phase)
    n = 400_000
    r = legs.LEG_RADIUS * np.sqrt(rng.random(n))
    a = rng.uniform(0, 2 * math.pi, n)
    pts = centres[rng.integers(0, 2, n)] + np.column_stack([r * np.cos(a), r * np.sin(a)])
    assert legs.legs_extent(heading, speed, t, phase) == pytest.approx(
        4.0 * np.cov(pts.T), abs=2e-4)


def test_the_legs_swing_in_turn_and_stand_side_by_side():
    h = 0.0
    # standing: side by side, 2 HIP apart across the heading
    d = np.diff(legs.leg_centres(np.zeros(2), h, 0.0, 0.4, 0.3), axis=0)[0]
    assert d == pytest.approx([0.0, -2 * legs.HIP])
    # walking: fore and aft in opposite phase, at most MAX_SWING each side, a gait cycle
    # every 1 / CADENCE s
    t = np.linspace(0.01, 1.0 / legs.CADENCE, 200, endpoint=False)   # t = 0: side by side
    fore = np.array([legs.leg_centres(np.zeros(2), h, 2.0, ti, 0.0)[:, 0] for ti in t])
    assert fore[:, 0] == pytest.approx(-fore[:, 1])
    assert fore[:, 0].max() == pytest.approx(legs.MAX_SWING, abs=1e-3)
    assert np.count_nonzero(np.diff(np.sign(fore[:, 0])) != 0) == 1   # one crossing


def test_a_walker_at_leg_height_returns_two_leg_arcs():
    """Walking across the beams 2 m ahead, the scan shows two clusters about a leg wide,
    their centres as far apart as the legs; now and then one hides the other."""
    walker = SimObject((2.0, -1.0), (0.0, 1.0), shape='legs')
    laser = LaserSpec(n_beams=721, dropout=0.0)
    clusters = []
    for scan, truth in simulate(Scene(objects=(walker,), laser=laser), 2.0, 1):
        r = np.asarray(scan.ranges, float)
        beams = np.isfinite(r).nonzero()[0]
        runs = np.split(beams, np.nonzero(np.diff(beams) > 1)[0] + 1)
        clusters.append(len([b for b in runs if len(b)]))
        assert len(truth) == 1 and truth[0].visible_beams == len(beams)
    assert max(clusters) == 2 and min(clusters) == 1


def test_leg_twins_keep_everything_but_the_walkers_shape():
    from extended_tracker.sim.laser import mixed_traffic_scene

    body = mixed_traffic_scene()
    twin = at_leg_height(body)
    for b, t in zip(body.objects, twin.objects):
        assert (b.start, b.velocity, b.t_start, b.stops) == (t.start, t.velocity, t.t_start,
                                                               t.stops)
        assert t.shape == ('legs' if b.kind == 'pedestrian' else b.shape)


@pytest.mark.parametrize('n', [1, 4, 15])
def test_counting_scenes_keep_people_apart_but_companions(n):
    scene = counting_scene(n, seed=n)
    assert len(scene.objects) == n
    times = np.arange(0.0, COUNTING_SECONDS, 0.05)
    paths = [ob.centres(times) for ob in scene.objects]
    for i in range(n):
        for j in range(i + 1, n):
            d = np.linalg.norm(paths[i] - paths[j], axis=1)
            if not np.isfinite(d).any():
                continue
            a, b = scene.objects[i], scene.objects[j]
            together = a.t_start == b.t_start and a.velocity == b.velocity
            if together:        # side by side, the companion gap across the path
                assert np.nanmin(d) == pytest.approx(COMPANION_GAP)
            else:
                assert np.nanmin(d) >= MIN_GAP - 0.05
