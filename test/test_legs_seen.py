"""
Whether the scans show legs (``sensing.legs``): leg pairs counted on scans cast here by
hand, on the simulator's walkers at leg and at body height, and the smallest distance
threshold the partitioning gets once they have been seen.
"""

import math

import numpy as np
import pytest

from extended_tracker.config import from_dict, preset
from extended_tracker.filter import update as update_module
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.sensing import legs as legs_module
from extended_tracker.sensing.legs import leg_pairs, LegEvidence, legs_seen, scan_config
from extended_tracker.sensing.scan import Header, scan_to_points, ScanData, Stamp
from extended_tracker.sim.laser import LaserSpec, Scene, SimObject, simulate

LEG = 0.06                                  # a leg's radius (m)
BEAMS = np.radians(np.arange(-90.0, 90.0, 0.35))


def cast(discs, wall=5.0, beams=BEAMS):
    """Ranges of beams from the origin to the nearest of ``discs`` ((x, y, radius)) or to
    a wall ``wall`` m ahead (x = wall)."""
    d = np.column_stack([np.cos(beams), np.sin(beams)])
    ranges = wall / np.maximum(d[:, 0], 1e-9)
    for x, y, r in discs:
        along = d @ np.array([x, y])
        off2 = x * x + y * y - along ** 2
        hit = (off2 < r * r) & (along > 0)
        ranges = np.where(hit, np.minimum(ranges, along - np.sqrt(np.abs(r * r - off2))),
                          ranges)
    return np.minimum(ranges, 20.0)


def scan_of(ranges, beams=BEAMS):
    inc = float(beams[1] - beams[0])
    msg = ScanData(Header(Stamp(1, 0), 'laser'), float(beams[0]), float(beams[-1]), inc, 0.05,
                   19.0, np.asarray(ranges, float))
    return scan_to_points(msg)


@pytest.mark.parametrize('beams', [BEAMS, BEAMS[::-1]])    # also a negative increment
def test_two_legs_side_by_side_are_a_pair(beams):
    ranges = cast([(2.0, 0.125, LEG), (2.0, -0.125, LEG)], beams=beams)
    assert leg_pairs(scan_of(ranges, beams)) == 1


def test_a_dropout_inside_a_leg_does_not_break_it():
    ranges = cast([(2.0, 0.125, LEG), (2.0, -0.125, LEG)])
    on_leg = np.nonzero(ranges < 2.5)[0]
    ranges[on_leg[2]] = np.inf                  # one beam of the first leg returns nothing
    assert leg_pairs(scan_of(ranges)) == 1


@pytest.mark.parametrize('discs', [
    [(2.0, 0.0, 0.22)],                               # a torso: one wide cluster
    [(2.0, 0.35, LEG), (2.0, -0.35, LEG)],            # two lone legs 0.7 m apart
    [(2.0, 0.125, 0.2), (2.0, -0.3, 0.2)],            # two torsos side by side
    [(3.0, 0.0, 0.3), (2.5, 0.0, 0.15)],              # a torso's edges either side of a
])                                                    # nearer one
def test_what_is_no_leg_pair(discs):
    assert leg_pairs(scan_of(cast(discs))) == 0


def test_far_legs_with_too_few_returns_are_no_pair():
    """At 9 m a beam every 1 deg hits a leg once or twice: fewer than a leg needs."""
    beams = np.radians(np.arange(-90.0, 90.0, 1.0))
    ranges = cast([(9.0, 0.125, LEG), (9.0, -0.125, LEG)], wall=12.0, beams=beams)
    assert 0 < np.count_nonzero(ranges < 10.0) <= 4
    assert leg_pairs(scan_of(ranges, beams)) == 0


def walker_scans(shape, seconds=3.0):
    walker = SimObject((3.0, -1.5), (0.0, 1.0), shape=shape)
    laser = LaserSpec(n_beams=513, dropout=0.0)
    return [scan for scan, _ in simulate(Scene(objects=(walker,), laser=laser), seconds, 1)]


def test_a_walker_shows_legs_at_leg_height_and_none_at_body_height():
    at_legs = [leg_pairs(scan_to_points(s)) for s in walker_scans('legs')]
    at_body = [leg_pairs(scan_to_points(s)) for s in walker_scans('ellipse')]
    assert np.mean(np.array(at_legs) == 1) > 0.5     # a leg hides the other now and then
    assert max(at_legs) == 1
    assert not any(at_body)


def test_a_wall_far_away_at_a_grazing_angle_is_no_leg_pair():
    """At 11 m a beam every 0.5 deg lands 0.1 m from the last on a wall across the view:
    the wall breaks into narrow clusters side by side, none standing out from the next."""
    beams = np.radians(np.arange(-15.0, 15.0, 0.5))
    ranges = cast([], wall=11.0, beams=beams)
    sp = scan_of(ranges, beams)
    assert np.all(np.hypot(*np.diff(sp.points, axis=0).T) > 0.09)
    assert leg_pairs(sp) == 0
    # a walker's legs in front of it are a pair
    ranges = cast([(6.0, 0.125, LEG), (6.0, -0.125, LEG)], wall=11.0, beams=beams)
    assert leg_pairs(scan_of(ranges, beams)) == 1


def test_the_legs_are_seen_once_a_quarter_of_the_last_second_showed_a_pair():
    """The share is an exponential average over MEMORY seconds: at 10 Hz a pair in every
    scan reaches SHARE after three scans (1 - 0.905^3 = 0.26); a pair now and then never
    does; once seen, the threshold stays raised."""
    cfg = from_dict({'partition': {'d_min': 0.2, 'leg_gap': 0.45}})
    legs, empty = scan_of(cast([(2.0, 0.125, LEG), (2.0, -0.125, LEG)])), scan_of(cast([]))
    keep = math.exp(-0.1 / legs_module.MEMORY)
    ev, share = LegEvidence(), 0.0
    for sp in [legs, empty] * 20:                 # a pair in every other scan: 0.5 on average
        ev = legs_seen(ev, sp, 0.1, cfg)
        share = keep * share + (1 - keep) * (sp is legs)
        assert ev.share() == pytest.approx(share) and ev.seen == (share >= legs_module.SHARE)
        if ev.seen:
            break
    assert ev.seen
    assert scan_config(cfg, ev).partition.d_min == 0.45
    assert scan_config(cfg, ev).model == cfg.model
    assert legs_seen(ev, empty, 10.0, cfg) is ev                   # seen: no more looking
    rare = LegEvidence()
    for k in range(200):                          # a pair in one scan in ten
        rare = legs_seen(rare, legs if k % 10 == 0 else empty, 0.1, cfg)
    assert not rare.seen and scan_config(cfg, rare) is cfg
    # never: leg_gap 0; and a d_min at or above leg_gap is never lowered
    assert legs_seen(LegEvidence(), legs, 10.0, from_dict({'partition': {'leg_gap': 0.0}})) \
        == LegEvidence()
    high = from_dict({'partition': {'d_min': 0.5}})
    assert scan_config(high, LegEvidence(((None, 1.0),), True)) is high


def test_each_scanner_keeps_its_own_share():
    """Two scanners take turns at 10 Hz each; one sees a leg pair in every scan, the
    other nothing (the walker is outside its view). Its own share reaches SHARE after
    three of its scans, as one scanner's would; one share over both scanners' scans,
    half of them empty, took thirteen (seven of its own)."""
    cfg = from_dict({'partition': {'d_min': 0.2, 'leg_gap': 0.45}})
    legs, empty = scan_of(cast([(2.0, 0.125, LEG), (2.0, -0.125, LEG)])), scan_of(cast([]))
    ev, turns = LegEvidence(), 0
    while not ev.seen:
        ev = legs_seen(ev, legs, 0.1, cfg, 'front')
        ev = legs_seen(ev, empty, 0.1, cfg, 'rear') if not ev.seen else ev
        turns += 1
    assert turns == 3 and ev.share('rear') == 0.0
    assert ev.share('front') == pytest.approx(1.0 - math.exp(-0.3 / legs_module.MEMORY))
    shared, scans = LegEvidence(), 0                # the scanners' scans in one average
    while not shared.seen:
        shared = legs_seen(shared, legs if scans % 2 == 0 else empty, 0.05, cfg)
        scans += 1
    assert scans == 13


def thresholds_used(monkeypatch, cfg, shape, seconds=2.0):
    """Per scan, the smallest threshold the partitioning was given, and diagnostics
    ``legs``."""
    seen = []
    build = update_module.build_partitions

    def recording(points, pcfg, *args, **kwargs):
        seen.append(pcfg.d_min)
        return build(points, pcfg, *args, **kwargs)

    monkeypatch.setattr(update_module, 'build_partitions', recording)
    state, used, flags = PipelineState.initial(cfg), [], []
    for scan in walker_scans(shape, seconds):
        seen.clear()
        state, res = step(state, scan, cfg)
        used.append(seen[0] if seen else None)
        flags.append(res.diagnostics['legs'])
    return used, flags


def test_the_pipeline_partitions_legs_as_one_once_it_has_seen_them(monkeypatch):
    cfg = from_dict({})
    used, flags = thresholds_used(monkeypatch, cfg, 'legs')
    first = flags.index(1)
    assert first >= 2 and all(flags[first:])         # three scans at 10 Hz
    assert set(used[:first]) - {None} == {cfg.partition.d_min}
    assert set(used[first:]) - {None} == {cfg.partition.leg_gap}


def test_at_body_height_the_threshold_stays_low(monkeypatch):
    cfg = from_dict({})
    used, flags = thresholds_used(monkeypatch, cfg, 'ellipse')
    assert not any(flags) and set(used) - {None} == {cfg.partition.d_min}


def test_told_the_height_the_legs_are_one_cell_from_the_first_scan(monkeypatch):
    used, _ = thresholds_used(monkeypatch, preset('leg_height'), 'legs', seconds=0.5)
    assert set(used) - {None} == {0.45}
    assert math.isclose(preset('leg_height').partition.d_min,
                        preset('leg_height').partition.leg_gap)
