"""The background warm-up: walls are learned, and what came into a beam is tracked."""

import numpy as np
import pytest

from extended_tracker.config import from_dict
from extended_tracker.evaluation.evaluate import scenario_scans
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.sensing import background
from extended_tracker.sensing.background import arrived, OPEN_SPACE_TIME, update_background
from extended_tracker.sensing.objects import object_beams
from extended_tracker.sensing.scan import scan_to_points
from extended_tracker.sim.laser import (
    clutter_scene, Drive, LaserSpec, Scene, SimObject, simulate, tutorial_scene,
)

ROOM = (((0.0, -6.0), (6.0, -6.0)), ((6.0, -6.0), (6.0, 6.0)), ((6.0, 6.0), (0.0, 6.0)))
CFG = from_dict({})


def _arrivals(ranges_per_scan, n_beams=5):
    """Feed whole scans of ranges (inf: no return); per scan, the beams that came."""
    (scan, _), = simulate(Scene((), laser=LaserSpec(n_beams=n_beams)), 0.1, seed=0)
    state, came = None, []
    for ranges in ranges_per_scan:
        scan.ranges = np.asarray(ranges, dtype=np.float32)
        sp = scan_to_points(scan)
        came.append(arrived(state, sp, CFG.background.margin))
        state, _ = update_background(state, sp, 0.1, CFG.background, np.zeros(n_beams, bool))
    return came


def test_a_return_nearer_than_anything_its_beam_returned_before_came():
    inf = np.inf
    came = _arrivals([[5, 5, 5, inf, 5],
                      [5, 2, 5, inf, 5],        # beam 1: something in front of the wall
                      [5, 5, 5, 3, 5],          # beam 3: nothing before, now 3 m
                      [5, 4.9, 5, inf, 8],      # beam 1: 10 cm off the wall; beam 4: farther
                      [5, 5, 5, 2, 5]])         # beam 3 since returned 3 m; beam 4 since 8 m
    assert not came[0].any()                    # nothing arrives in a first scan
    assert came[1].tolist() == [False, True, False, False, False]
    assert not came[2].any()                    # empty 0.2 s since start-up: a dropout
    assert not came[3].any()                    # within margin; a wall revealed is farther
    assert came[4].tolist() == [False, False, False, True, True]


def test_a_return_on_a_beam_that_looked_into_open_space_came():
    inf = np.inf
    empty = round(OPEN_SPACE_TIME / 0.1)                 # scans of 0.1 s
    came = _arrivals([[5, inf, inf, 5, 5]] * (empty - 1)
                     + [[5, inf, 4, 5, 5],              # beam 2: a wall after a dropout
                        [5, inf, 4, inf, 5],            # beam 3 drops out once
                        [5, 3, 4, 5, 5]])               # beam 1: open space until now
    assert not np.any(came[:-1])
    assert came[-1].tolist() == [False, True, False, False, False]


def warmup_points(objects, moving=False, seconds=1.4, walls=ROOM):
    """The pipeline in a room 6 m deep (or ``walls``) with ``objects`` in it (the scanner
    standing, or driving along the back wall at 0.3 m/s); the points that reached the
    filter in each scan of the warm-up. (A wall that ends in view is another matter: a
    piece of it under 1 m, cut off by a mover's shadow, is a small group with an end that
    stands out.)"""
    keys = ((0.0, 0.0, 0.0, 0.0), (10.0, 0.0, 3.0, 0.0)) if moving else ((0.0, 0.0, 0.0, 0.0),)
    # no dropouts: three in a row cut the wall, and a piece under 1 m at its end stands
    # out as the small group it then is
    scene = Scene(tuple(objects), walls=walls, laser=LaserSpec(dropout=0.0), drive=Drive(keys))
    state, kept = PipelineState.initial(CFG), []
    for scan, _, place in scenario_scans(scene, seconds, seed=3):
        state, res = step(state, scan, CFG, place=place)
        assert res.diagnostics.warmup == 1
        kept.append(res.points)
    return kept


# a cart 1.8 m long: no object, nor small, that the warm-up would pass as such
CART = dict(shape='rectangle', a=1.8, b=0.6, kind='cart')


def test_the_warm_up_passes_a_large_mover_that_came_in_front_of_the_wall():
    kept = warmup_points([SimObject((3.0, -4.0), (0.0, 2.0), **CART)])
    assert len(kept[0]) == 0                            # the first scan teaches the beams
    later = np.concatenate(kept[1:])
    assert len(later) > 300 and np.all((later[:, 0] < 4.0) & (np.abs(later[:, 1]) < 5.0))
    assert all(len(p) > 10 for p in kept[1:])


def test_the_warm_up_drops_a_large_thing_that_stands_and_what_a_driving_scanner_sees():
    across = SimObject((3.0, 0.0), shape='rectangle', a=0.6, b=1.8, kind='cart')
    assert all(len(p) == 0 for p in warmup_points([across]))
    # driving, every beam sees anew: once the scanner has moved (scan 2 at 0.3 m/s), only
    # a small piece of the cart with an open end passes now and then
    mover = SimObject((3.0, -4.0), (0.0, 2.0), **CART)
    driving = warmup_points([mover], moving=True)
    standing = warmup_points([mover])
    assert sum(map(len, driving[2:])) < 0.05 * sum(map(len, standing[2:]))


def test_the_warm_up_passes_a_large_mover_that_drives_in_through_open_space(monkeypatch):
    # one wall ahead; the cart drives into view from behind the scanner, where its beams
    # have looked into nothing since start-up; after 1 s over 1 m of it is in view
    ahead = (((6.0, -3.0), (6.0, 3.0)),)
    cart = SimObject((-1.5, -5.0), (2.0, 0.0), **CART)
    late = slice(10, None)
    kept = warmup_points([cart], walls=ahead)
    assert all(len(p) > 10 for p in kept[late])
    assert np.all(np.concatenate(kept)[:, 1] < -4.0)
    # a beam that must first have returned something passes none of it
    monkeypatch.setattr(background, 'OPEN_SPACE_TIME', np.inf)
    assert all(len(p) == 0 for p in warmup_points([cart], walls=ahead)[late])


def tutorial_scans(n):
    """The tutorial scene's first ``n`` scans (0.1 s apart)."""
    return [s for s, _ in simulate(tutorial_scene(), n / 10.0, seed=0)]


def tutorial_results(cfg, n):
    """The step results of a fresh pipeline over the tutorial's first ``n`` scans."""
    state, out = PipelineState.initial(cfg), []
    for s in tutorial_scans(n):
        state, res = step(state, s, cfg)
        out.append(res)
    return out


@pytest.mark.parametrize('warmup', [1.05, 1.55])
def test_the_warm_up_lasts_background_warmup_seconds_of_scans(warmup):
    """From the first scan (dt the default 0.1 s) the warm-up runs while the time so far
    is at most background.warmup: 10 scans at 10 Hz for 1.05 s, 15 for 1.55 s;
    the next scan tracks. (Off the scan grid: the time so far adds up 0.1 s steps, whose
    rounding takes 15 of them past 1.5.)"""
    cfg = from_dict({'background': {'enabled': True, 'warmup': warmup}})
    results = tutorial_results(cfg, 25)
    flags = [res.diagnostics['warmup'] for res in results]
    n = int(warmup * 10)
    assert flags == [1] * n + [0] * (25 - n)
    # meanwhile the returns of groups at most object_size across are detections (a person
    # standing there from start-up), and so are those nearer by over margin than any
    # earlier return of their beam (a walker who came); every other return is background
    for res, came, passed in warm_up_detections(cfg, results[:n]):
        assert len(res.background_points) + len(res.points) == res.diagnostics['detections']
        np.testing.assert_array_equal(res.points, passed)
    assert sum(came.any() for _, came, _ in warm_up_detections(cfg, results[:n])) >= n - 2
    # with objects off, only what came
    cfg = from_dict({'background': {'warmup': warmup, 'object_size': 0.0}})
    for res, came, passed in warm_up_detections(cfg, tutorial_results(cfg, n)):
        np.testing.assert_array_equal(res.points, passed)


def warm_up_detections(cfg, results):
    """Per warm-up result: it, the beams whose return came (nearer by over margin than
    every earlier return of the beam, or on a beam that returned nothing in the scans of
    the first OPEN_SPACE_TIME seconds and since), and the points that should pass: those
    and the small groups' (:func:`sensing.objects.object_beams`). The scans are 0.1 s
    apart."""
    farthest, margin = None, cfg.background.margin
    for k, (res, scan) in enumerate(zip(results, tutorial_scans(len(results)))):
        sp = scan_to_points(scan)
        small = object_beams(sp, cfg.background.object_size, margin)[1]
        ranges = np.where(np.isfinite(sp.ranges), sp.ranges, np.nan)
        with np.errstate(invalid='ignore'):
            came = (sp.ranges < farthest - margin if farthest is not None
                    else np.zeros_like(small))              # NaN (never returned): False
        farthest = ranges if farthest is None else np.fmax(farthest, ranges)
        if (k + 1) * 0.1 >= OPEN_SPACE_TIME - 1e-9:        # nothing yet: open space
            farthest = np.where(np.isnan(farthest), np.inf, farthest)
        yield res, came, sp.points[(small | came)[sp.beam]]


def test_the_clutter_rate_is_learned_from_the_first_scan_after_the_warm_up():
    """The warm-up shows the filter only what stands out or came, so its clutter count
    is no measure of the scan's: the learned rate starts after it, near the simulated
    15 returns per scan (learned during the warm-up it began near 4 and was still
    below 8 a second and a half later)."""
    scene = clutter_scene()
    state, rates = PipelineState.initial(CFG), []
    for scan, _ in simulate(scene, 2.0, seed=0):
        state, res = step(state, scan, CFG)
        rates.append((res.diagnostics['warmup'], state.filter.clutter_rate))
    warm = [rate for flag, rate in rates if flag]
    after = [rate for flag, rate in rates if not flag]
    assert len(warm) >= 10 and all(rate is None for rate in warm)
    assert all(rate > 0.75 * scene.laser.clutter_per_scan for rate in after[:5]), after
