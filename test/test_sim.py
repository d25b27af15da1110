"""Scenes of the laser simulator: nobody walks through anybody."""

import math

import numpy as np
import pytest

from extended_tracker.evaluation.evaluate import SCENARIOS
from extended_tracker.sim import legs
from extended_tracker.sim.laser import bounding_gap, crowd_scene, GAP_STEP, SimObject


def test_bounding_gap_of_two_walkers_passing_side_by_side():
    # head-on along x, 0.8 m apart in y; they meet at t = 2 s: the centres are then 0.8 m
    # apart and each bounding circle has the semi-major axis, 0.25 m, as its radius
    a = SimObject((0.0, 0.0), (1.0, 0.0))
    b = SimObject((4.0, 0.8), (-1.0, 0.0))
    assert bounding_gap(a, b, 5.0) == pytest.approx(0.8 - 0.5, abs=1e-9)
    # before they meet the gap is larger; a car's circle holds its corners
    assert bounding_gap(a, b, 1.0) == pytest.approx(math.hypot(2.0, 0.8) - 0.5, abs=1e-9)
    car = SimObject((10.0, 0.0), shape='rectangle', a=4.0, b=1.8)
    assert car.radius == pytest.approx(0.5 * math.hypot(4.0, 1.8))
    # never alive together: no gap to speak of
    late = SimObject((0.0, 0.0), t_start=6.0)
    assert bounding_gap(a, late, 5.0) == math.inf


def discs(ob, t):
    """Circles ((x, y), r) that hold the object at ``t``: its two legs, else its bounding
    circle (none while it is not alive)."""
    if not ob.alive(t):
        return []
    c, v, h = ob.state(t)
    if ob.shape == 'legs':
        return [(p, legs.LEG_RADIUS)
                for p in legs.leg_centres(c, h, float(np.hypot(*v)), t, ob.gait_phase)]
    return [(c, ob.radius)]


def legs_gap(a, b, seconds):
    """The least gap between the circles of ``a`` and ``b`` (at least one of them a
    walker at leg height, whose legs swing fore and aft of its bounding circle's centre
    but never across its path far) over the first ``seconds``, every GAP_STEP."""
    gaps = [np.linalg.norm(ca - cb) - ra - rb
            for t in np.arange(0.0, seconds, GAP_STEP)
            for ca, ra in discs(a, t) for cb, rb in discs(b, t)]
    return min(gaps, default=math.inf)


@pytest.mark.slow
@pytest.mark.parametrize('name', list(SCENARIOS))
def test_no_two_objects_of_a_scenario_overlap(name):
    factory, seconds, *_ = SCENARIOS[name]
    scene = factory()
    objs = (scene[0] if isinstance(scene, list) else scene).objects   # one per scanner
    gaps = {(i, j): (legs_gap(objs[i], objs[j], seconds) if 'legs' in
                     (objs[i].shape, objs[j].shape) else bounding_gap(objs[i], objs[j], seconds))
            for i in range(len(objs)) for j in range(i + 1, len(objs))}
    # bounding circles never overlap, so neither do the shapes: two people walking
    # through one another give one blob that no laser can take apart
    assert min(gaps.values(), default=math.inf) >= 0.0, \
        {k: round(v, 2) for k, v in gaps.items() if v < 0.0}


@pytest.mark.slow
def test_crowd_walkers_are_redrawn_until_nobody_overlaps():
    free = crowd_scene(20, seed=5).objects
    kept = crowd_scene(20, seed=5, seconds=10.0).objects
    assert len(kept) == 20

    def overlaps(objs):
        return sum(bounding_gap(a, b, 10.0) < 0.0
                   for i, a in enumerate(objs) for b in objs[i + 1:])
    # drawn freely, several pairs of this crowd pass through one another
    assert overlaps(free) >= 3
    assert overlaps(kept) == 0
    # one random stream: the walkers before the first redraw are the same
    assert kept[0] == free[0]


@pytest.mark.slow
def test_a_crowd_that_cannot_fit_is_refused_not_drawn_forever(monkeypatch):
    import extended_tracker.sim.laser as laser

    drawn = []

    def counted(*args, **kwargs):
        drawn.append(1)
        return SimObject(*args, **kwargs)

    monkeypatch.setattr(laser, 'SimObject', counted)
    # twelve walkers on a ring 1.5-1.6 m out, for 2 s: they cannot all keep apart; given
    # up after MAX_DRAWS draws a walker
    with pytest.raises(ValueError, match=r'walkers fit without overlapping in 2.0 s '
                                         r'\(2400 draws\)'):
        crowd_scene(12, seed=1, range_max=2.0, seconds=2.0)
    assert len(drawn) == laser.MAX_DRAWS * 12 == 2400


def test_the_bundled_bag_is_what_its_command_writes(tmp_path):
    """bags/README.md: `extended-tracker simulate bags/demo --scene demo --seed 7
    --duration 15` reproduces the bundled bag, scan for scan and byte for byte, and its
    truth.json."""
    import json
    from pathlib import Path

    from rosbags.rosbag2 import Reader

    from extended_tracker.cli import main

    bundled = Path(__file__).resolve().parents[1] / 'bags' / 'demo'
    made = tmp_path / 'demo'
    assert main(['simulate', str(made), '--scene', 'demo', '--seed', '7',
                 '--duration', '15']) == 0

    def records(path):
        with Reader(path) as r:
            return [(c.topic, c.msgtype, t, bytes(raw)) for c, t, raw in r.messages()]

    want, got = records(bundled), records(made)
    assert len(want) == 150 and [r[:3] for r in got] == [r[:3] for r in want]
    if got != want:
        # numpy's sin, cos and arctan2 kernels differ in the last bit between CPUs: on
        # another machine a float32 range may round the other way; nothing more
        from extended_tracker.bag.bagio import message_typestore, SCAN_TYPE

        store = message_typestore()
        for (*_, a), (*_, b) in zip(got, want):
            ma, mb = (store.deserialize_cdr(x, SCAN_TYPE) for x in (a, b))
            assert ma.header == mb.header and ma.angle_min == mb.angle_min
            np.testing.assert_array_max_ulp(ma.ranges, mb.ranges, maxulp=1)
    truth_made = json.loads((made / 'truth.json').read_text())
    truth_bundled = json.loads((bundled / 'truth.json').read_text())
    for info in (truth_made['info'], truth_bundled['info']):
        del info['bag'], info['truth']                # where each was written
        if got != want:
            del info['scan_digest']                   # of the last bits above
    assert truth_made == truth_bundled
