"""The background warm-up: walls are learned, and what came into a beam is tracked."""

import numpy as np

from extended_tracker.config import from_dict
from extended_tracker.evaluation.evaluate import scenario_scans
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.sensing.background import arrived, update_background
from extended_tracker.sensing.scan import scan_to_points
from extended_tracker.sim.laser import Drive, LaserSpec, Scene, SimObject, simulate

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
    assert not came[2].any()                    # a beam that never returned: open or dropout
    assert not came[3].any()                    # within margin; a wall revealed is farther
    assert came[4].tolist() == [False, False, False, True, True]


def warmup_points(objects, moving=False, seconds=1.4):
    """The pipeline in a room 6 m deep with ``objects`` in it (the scanner standing, or
    driving along the back wall at 0.3 m/s); the points that reached the filter in each
    scan of the warm-up. (A wall that ends in view is another matter: a piece of it under
    1 m, cut off by a mover's shadow, is a small group with an end that stands out.)"""
    keys = ((0.0, 0.0, 0.0, 0.0), (10.0, 0.0, 3.0, 0.0)) if moving else ((0.0, 0.0, 0.0, 0.0),)
    # no dropouts: three in a row cut the wall, and a piece under 1 m at its end stands
    # out as the small group it then is
    scene = Scene(tuple(objects), walls=ROOM, laser=LaserSpec(dropout=0.0), drive=Drive(keys))
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
