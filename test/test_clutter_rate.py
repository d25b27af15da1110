"""
The clutter rate the filter learns from the scans (``model.clutter_memory``).

Oracles: the PHD posterior odds that a lone detection is clutter, which scale with the
clutter rate; a detection nothing else can explain; the exponential average's step
response; and point scenes whose clutter rate is known.
"""

from dataclasses import replace

import numpy as np
import pytest

from extended_tracker.config import from_dict
from extended_tracker.filter.clutter import clutter_rate_in_use, learned_clutter_rate
from extended_tracker.sim.points import point_scene, PointObject
from extended_tracker.tracker import filter_step, TrackerState

DT = 0.1


def _cfg(**model):
    return from_dict({'model': {'surveillance_area': 400.0, **model}})


def _tracked(cfg, scans=20, seed=0):
    """A state tracking one object at rest at (2, 1), no clutter, nothing learned."""
    rng = np.random.default_rng(seed)
    ob = [PointObject((2.0, 1.0), (0.0, 0.0), rate=8.0)]
    state = TrackerState.initial(cfg)
    for k in range(scans):
        pts, _ = point_scene(ob, k * DT, rng, clutter_rate=0.0)
        state, _, _ = filter_step(state, pts, DT, cfg)
    return replace(state, filter=replace(state.filter, clutter_rate=None))


def _count(state, points, cfg):
    """The scan's clutter count: the first learned rate is that scan's count as it is."""
    after, _, _ = filter_step(state, np.asarray(points, dtype=float), DT, cfg)
    return after.filter.clutter_rate


def test_a_detection_nothing_can_explain_is_clutter():
    cfg = _cfg()
    # a lone return far from any object: no object is there, and a birth needs two
    assert _count(TrackerState.initial(cfg), [[5.0, 5.0]], cfg) == pytest.approx(1.0)
    assert _count(_tracked(cfg), [[-6.0, -6.0]], cfg) == pytest.approx(1.0)
    # no detections: no clutter
    assert _count(_tracked(cfg), np.zeros((0, 2)), cfg) == 0.0


def test_clutter_odds_of_a_lone_detection_scale_with_the_rate_in_phd():
    # PHD: P(clutter) = lambda c / (lambda c + D) for a lone detection, so its odds are
    # lambda c / D: linear in the clutter rate, whatever the object's likelihood D is
    state = _tracked(_cfg(mode='phd'))
    z = [[2.15, 1.05]]
    counts = {lam: _count(state, z, _cfg(mode='phd', clutter_rate=lam))
              for lam in (0.5, 2.0, 8.0)}
    assert all(0.0 < c < 1.0 for c in counts.values()), counts
    odds = {lam: c / (1.0 - c) for lam, c in counts.items()}
    assert odds[2.0] / odds[0.5] == pytest.approx(4.0, rel=1e-6)
    assert odds[8.0] / odds[0.5] == pytest.approx(16.0, rel=1e-6)


def test_the_average_forgets_over_the_memory():
    cfg = _cfg(clutter_memory=2.0)
    assert learned_clutter_rate(None, 6.0, DT, cfg) == 6.0
    # a step from 0 to 10 held for one memory: 1 - 1/e of the way, whatever the period
    for dt in (0.025, 0.1, 0.5):
        rate = 0.0
        for _ in range(round(2.0 / dt)):
            rate = learned_clutter_rate(rate, 10.0, dt, cfg)
        assert rate == pytest.approx(10.0 * (1.0 - np.exp(-1.0)), rel=1e-9)
    assert learned_clutter_rate(3.0, 10.0, DT, _cfg(clutter_memory=0.0)) is None


def test_the_update_assumes_the_larger_of_told_and_learned():
    cfg = _cfg(clutter_rate=2.0)
    state = TrackerState.initial(cfg).filter
    assert clutter_rate_in_use(state, cfg) == 2.0
    assert clutter_rate_in_use(replace(state, clutter_rate=0.3), cfg) == 2.0
    assert clutter_rate_in_use(replace(state, clutter_rate=11.0), cfg) == 11.0


def _learn(clutter, seed, scans=100, cfg=None):
    """Track two walkers among uniform clutter of the given rate; the learned rate per
    scan and the number of objects shown per scan."""
    cfg = cfg or _cfg()
    rng = np.random.default_rng(seed)
    objects = [PointObject((-4.0, -2.0), (0.8, 0.3)), PointObject((3.0, 4.0), (-0.5, -0.6))]
    state = TrackerState.initial(cfg)
    rates, shown = [], []
    for k in range(scans):
        pts, _ = point_scene(objects, k * DT, rng, clutter_rate=clutter)
        state, est, _ = filter_step(state, pts, DT, cfg)
        rates.append(state.filter.clutter_rate)
        shown.append(len(est))
    return np.array(rates), np.array(shown)


@pytest.mark.parametrize('clutter', [4.0, 12.0])
def test_the_learned_rate_finds_the_true_rate(clutter):
    # after three memories the average has forgotten its start; clutter that lands on a
    # walker is taken as the walker's, so the learned rate may be a little low
    for seed in range(3):
        rates, _ = _learn(clutter, seed)
        assert 0.75 * clutter < rates[-30:].mean() < 1.1 * clutter, (seed, rates[-30:])


def test_without_clutter_the_learned_rate_stays_below_the_told_one():
    for seed in range(3):
        rates, _ = _learn(0.0, seed)
        assert rates[10:].max() < 0.2, rates


def test_learning_the_rate_keeps_heavy_clutter_from_becoming_objects():
    # told 1 clutter return per scan, given 30: without learning, pairs of clutter
    # returns are born as objects; two walkers are all there is
    false = {}
    for memory in (0.0, 3.0):
        shown = np.concatenate([_learn(30.0, seed, cfg=_cfg(clutter_memory=memory))[1][40:]
                                for seed in range(3)])
        false[memory] = np.mean(np.maximum(shown - 2, 0))
    assert false[0.0] > 0.5 and false[3.0] < 0.1 * false[0.0], false
