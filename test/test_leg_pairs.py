"""
A walker's two legs tracked as two labels become one track (``reduction.pair_scans``,
on by default); two objects that only pass each other stay two.

The joined component is checked against sampling (its centre, extent and kinematic
covariance are moments of the two parts), the thinned cardinality pmf against
enumeration, and the rule on synthetic legs with the filter running.
"""

from dataclasses import replace
from itertools import product

import numpy as np
import pytest

from extended_tracker.config import from_dict, PRESETS
from extended_tracker.filter.cardinality import thin_cardinality
from extended_tracker.filter.mixture import IW_OFFSET, Mixture
from extended_tracker.filter.reduction import join_parts
from extended_tracker.filter.state import FilterState
from extended_tracker.tracker import filter_step, TrackerState
from extended_tracker.tracks.record import TrackRecord

from mixtures import with_fields


def leg_config(pair_scans, mode='cphd'):
    legs = {k: dict(v) for k, v in PRESETS['leg_height'].items()}
    legs.setdefault('reduction', {})['pair_scans'] = pair_scans
    legs['model'] = {'mode': mode}
    return from_dict(legs)


def two_parts():
    m = np.array([[1.0, 0.2, 0.9, 0.1], [1.3, -0.1, 0.2, -0.3]])
    P = np.array([np.diag([0.01, 0.02, 0.3, 0.2]), np.diag([0.03, 0.01, 0.1, 0.4])])
    P[0, 0, 2] = P[0, 2, 0] = 0.02
    X = np.array([[[0.010, 0.003], [0.003, 0.006]], [[0.004, -0.001], [-0.001, 0.012]]])
    v = np.array([14.0, 25.0])
    return Mixture(np.array([0.9, 0.7]), np.array([24.0, 12.0]), np.array([3.0, 2.0]), m, P,
                   v, X * (v - IW_OFFSET)[:, None, None], np.array([4, 9]))


def test_the_joined_component_holds_the_moments_of_both_parts():
    mix = two_parts()
    weights = np.array([1.0, 0.8])                     # the labels' total weights
    out = join_parts(mix, np.array([0, 1]), weights, 4)
    rate = mix.alpha / mix.beta                        # 8 and 6 returns a scan
    # returns of the two parts: each part's share in proportion to weight times rate,
    # spread over its expected extent about its centre
    rng = np.random.default_rng(0)
    share = weights * rate / np.sum(weights * rate)
    n = 400_000
    k = rng.choice(2, size=n, p=share)
    X = mix.V / (mix.v - IW_OFFSET)[:, None, None]
    pts = np.empty((n, 2))
    states = np.empty((n, 4))
    for part in (0, 1):
        sel = k == part
        pts[sel] = rng.multivariate_normal(mix.m[part, :2], X[part], sel.sum())
        states[sel] = rng.multivariate_normal(mix.m[part], mix.P[part], sel.sum())
    assert np.allclose(out.m[0], states.mean(axis=0), atol=3e-3)
    assert np.allclose(out.m[0, :2], pts.mean(axis=0), atol=1e-3)
    assert np.allclose(out.expected_extent()[0], np.cov(pts.T), atol=4e-4)
    assert np.allclose(out.P[0], np.cov(states.T), atol=4e-3)
    # one object: the heavier part's weight, the returns of both, the senior's label,
    # no more certain about rate or extent than the less certain part
    assert out.w[0] == 1.0 and out.label[0] == 4
    assert out.expected_rate()[0] == pytest.approx(rate.sum())
    assert out.beta[0] == 2.0 and out.v[0] == 14.0


def enumerated_thinning(p, removed):
    """The pmf after whole objects are taken away one by one (the last with the fractional
    part as its probability), none from an empty scene: every branch enumerated."""
    steps = [1.0] * int(removed) + ([removed - int(removed)] if removed % 1 else [])
    out = np.zeros_like(p)
    for n, pn in enumerate(p):
        for taken in product([0, 1], repeat=len(steps)):
            prob, left = pn, n
            for f, t in zip(steps, taken):
                prob *= f if t else 1.0 - f
                if t and left:
                    left -= 1
            out[left] += prob
    return out


@pytest.mark.parametrize('removed', [0.4, 1.0, 1.3, 2.75])
def test_thinning_the_cardinality_matches_enumeration(removed):
    rng = np.random.default_rng(int(removed * 100))
    p = rng.dirichlet(np.ones(9))
    got = np.exp(thin_cardinality(np.log(p), removed))
    assert np.allclose(got, enumerated_thinning(p, removed), atol=1e-14, rtol=1e-12)
    assert got.sum() == pytest.approx(1.0, abs=1e-14)
    # far from the empty scene the mean falls by exactly what was taken away
    far = np.zeros(12)
    far[6:9] = [0.2, 0.5, 0.3]
    with np.errstate(divide='ignore'):
        log_far = np.log(far)
    mean = np.arange(12) @ np.exp(thin_cardinality(log_far, removed))
    assert mean == pytest.approx(np.arange(12) @ far - removed, abs=1e-12)


def legs(rng, t, centre, velocity, gap=0.35, n=8):
    """Returns of one walker's two legs, ``gap`` apart across its heading; the legs take
    turns to swing (one moves at twice the walking speed while the other stands)."""
    c = np.asarray(centre) + np.asarray(velocity) * t
    v = np.asarray(velocity, dtype=float)
    heading = v / max(np.linalg.norm(v), 1e-9)
    side = np.array([-heading[1], heading[0]])
    stride = 0.15 * np.sin(2 * np.pi * 1.0 * t) * heading      # one leg ahead, then the other
    feet = [c + 0.5 * gap * side + stride, c - 0.5 * gap * side - stride]
    return np.vstack([f + rng.normal(0, 0.03, (n, 2)) for f in feet])


def tracked_legs(cfg, left, right):
    """A state with the legs already tracked as two labels (as a replay leaves them)."""
    state = TrackerState.initial(cfg)
    k = 2
    m = np.array([[*left, 1.0, 0.0], [*right, 1.0, 0.0]])
    P = np.broadcast_to(np.diag([0.03 ** 2, 0.03 ** 2, 0.2, 0.2]), (k, 4, 4)).copy()
    v = np.full(k, 30.0)
    V = np.broadcast_to((30.0 - IW_OFFSET) * 0.07 ** 2 * np.eye(2), (k, 2, 2)).copy()
    mix = Mixture(np.ones(k), np.full(k, 40.0), np.full(k, 5.0), m, P, v, V,
                  np.array([3, 5]))
    log_card = np.full(cfg.model.n_max + 1, -np.inf)
    log_card[2] = 0.0
    return with_fields(state, mixture=mix, log_card=log_card, next_label=6,
                   reported=np.array([3, 5]), reported_scans=np.array([40, 30]),
                   reported_hits=np.array([40, 30]),
                   reported_origin=np.array([left, right]), reported_travel=np.zeros(2),
                   reported_size=np.zeros(2))


@pytest.mark.parametrize('pair_scans,mode', [(0, 'cphd'), (3, 'cphd'), (0, 'phd'),
                                             (3, 'phd')])
def test_two_tracked_legs_of_one_walker_become_one_track(pair_scans, mode):
    cfg = leg_config(pair_scans, mode)
    rng = np.random.default_rng(7)
    state = tracked_legs(cfg, (2.0, 0.175), (2.0, -0.175))
    shown, joins = [], []
    for k in range(30):
        state, est, diag = filter_step(state, legs(rng, 0.1 * (k + 1), (2.0, 0.0), (1.0, 0.0)),
                                       0.1, cfg)
        shown.append(est.label.tolist())
        joins.append(diag.joined_labels)
    joined = sum(joins)
    if pair_scans:
        # joined in the third scan together, not before, under the label reported longer
        assert joined == 1 and joins.index(1) == pair_scans - 1
        assert all(s == [3] for s in shown[3:])
        if mode == 'cphd':
            assert int(state.filter.log_card.argmax()) == 1
        assert np.sum(state.filter.mixture.w) == pytest.approx(1.0, abs=0.1)
    else:
        # what the leg-height recordings showed: two ids side by side to the end
        assert joined == 0
        assert shown[-1] == [3, 5]


@pytest.mark.parametrize('pair_scans', [0, 3])
def test_a_leg_born_beside_its_walker_is_never_shown(pair_scans):
    """A walker tracked as one leg: the other, once tracked on its own, is joined before
    it is confirmed (pair_scans is the confirmation's count)."""
    cfg = leg_config(pair_scans)
    rng = np.random.default_rng(11)
    state = tracked_legs(cfg, (2.0, 0.175), (2.0, -0.175))
    mix = state.filter.mixture.take(np.array([0]))
    log_card = np.full(cfg.model.n_max + 1, -np.inf)
    log_card[1] = 0.0
    state = with_fields(state, mixture=mix, log_card=log_card, reported=np.array([3]),
                    reported_scans=np.array([40]), reported_hits=np.array([40]),
                    reported_origin=np.array([[2.0, 0.175]]),
                    reported_travel=np.full(1, 4.0), reported_size=np.zeros(1))
    seen = set()
    for k in range(30):
        state, est, _ = filter_step(state, legs(rng, 0.1 * (k + 1), (2.0, 0.0), (1.0, 0.0)),
                                    0.1, cfg)
        seen.update(est.label.tolist())
    if pair_scans:
        assert seen == {3}
    else:
        assert 3 in seen and len(seen) > 1


def test_two_walkers_passing_each_other_stay_two():
    """Legs of two people walking past each other 0.45 m apart: close for a few scans,
    but their velocities differ by far more than one leg's swing."""
    cfg = leg_config(3)
    rng = np.random.default_rng(5)
    state = tracked_legs(cfg, (1.0, 0.225), (3.0, -0.225))
    state = with_fields(state, mixture=replace(state.filter.mixture, m=np.array(
        [[1.0, 0.225, 1.5, 0.0], [3.0, -0.225, -1.5, 0.0]])))
    joined = 0
    for k in range(14):
        t = 0.1 * (k + 1)
        a = np.array([1.0 + 1.5 * t, 0.225]) + rng.normal(0, 0.03, (8, 2))
        b = np.array([3.0 - 1.5 * t, -0.225]) + rng.normal(0, 0.03, (8, 2))
        state, est, diag = filter_step(state, np.vstack([a, b]), 0.1, cfg)
        joined += diag.joined_labels
    assert joined == 0
    assert est.label.tolist() == [3, 5]
    assert est.m[est.label == 3, 0] > 2.5 and est.m[est.label == 5, 0] < 1.5


def test_old_labels_that_moved_are_no_pair_and_settled_ones_pair_only_together():
    """``join_pairs`` with the record's history: two labels shown 20 scans or more that
    have moved are two objects, however alike they move (people passing close and slowly:
    the bundled demo's B and C, 1.4 m/s apart, became one); a settled label (old, not
    moved) pairs with another settled one only (a standing person's legs), not with a
    young walker passing it."""
    from extended_tracker.tracks.pairs import join_pairs, SETTLED_SCANS

    cfg = leg_config(3)
    filt = FilterState.initial(cfg)
    parts = _parts([3, 5], [0.0, 0.3], (0.1, 0.1))
    parts.m[:, 2:] = [[0.0, 0.55], [0.9, -0.55]]                 # 1.4 m/s apart

    def forming(scans, travel):
        record = TrackRecord(reported=np.array([3, 5]), reported_scans=np.array(scans),
                             reported_travel=np.array(travel, float))
        return join_pairs(filt, record, parts, cfg)[1].pairs.tolist()

    old, young = SETTLED_SCANS, SETTLED_SCANS - 1
    assert forming([old, young], [2.0, 0.2]) == [[3, 5]]      # a walker and a young leg
    assert forming([old, old], [2.0, 3.0]) == []              # two people passing
    parts.m[:, 2:] = [[1.0, 0.1], [1.2, -0.3]]                  # 0.45 m/s apart: still two
    assert forming([old, old], [2.0, 3.0]) == []
    parts.m[:, 2:] = [[0.0, 0.55], [0.9, -0.55]]
    assert forming([old, old], [0.1, 0.2]) == [[3, 5]]        # a standing person's legs
    assert forming([old, young], [0.1, 0.2]) == []            # a walker passing a post


def test_two_parts_farther_apart_than_pair_distance_stay_two():
    cfg = leg_config(3)
    rng = np.random.default_rng(9)
    state = tracked_legs(cfg, (2.0, 0.35), (2.0, -0.35))
    for k in range(20):
        state, est, diag = filter_step(
            state, legs(rng, 0.1 * (k + 1), (2.0, 0.0), (1.0, 0.0), gap=0.7), 0.1, cfg)
        assert diag.joined_labels == 0
    assert est.label.tolist() == [3, 5]


def test_a_leg_whose_pair_forms_after_its_birth_is_never_shown():
    """The second leg is first seen 0.75 m out, beyond pair_distance, then beside the
    walker: its pair forms a scan or more after its birth, and it would be confirmed
    before the pair had its three scans. A part never shown waits while its pair forms."""
    cfg = leg_config(3)
    rng = np.random.default_rng(11)
    state = tracked_legs(cfg, (2.0, 0.0), (2.0, -0.35))
    log_card = np.full(cfg.model.n_max + 1, -np.inf)
    log_card[1] = 0.0
    state = with_fields(state, mixture=state.filter.mixture.take(np.array([0])), log_card=log_card,
                    reported=np.array([3]), reported_scans=np.array([40]),
                    reported_hits=np.array([40]), reported_origin=np.array([[2.0, 0.0]]),
                    reported_travel=np.zeros(1), reported_size=np.zeros(1))
    seen, joined = set(), 0
    for k in range(20):
        t = 0.1 * (k + 1)
        pts = [np.array([2.0 + t, 0.0]) + rng.normal(0, 0.03, (8, 2))]
        if k >= 5:
            gap = 0.75 if k == 5 else 0.4
            pts.append(np.array([2.0 + t, -gap]) + rng.normal(0, 0.03, (8, 2)))
        state, est, diag = filter_step(state, np.vstack(pts), 0.1, cfg)
        seen.update(est.label.tolist())
        joined += diag.joined_labels
    assert joined == 1 and seen == {3}


def test_two_parts_shown_apart_stay_shown_while_their_pair_forms():
    """Two parts tracked and shown 0.7 m apart (not a pair), then 0.35 m: the pair forms
    over pair_scans (3) scans, and meanwhile both stay reported (only a part never shown
    waits for its pair); then they are one, under the senior label. (Both shown fewer
    than SETTLED_SCANS scans: two old movers are no pair,
    test_old_labels_that_moved_are_no_pair_and_settled_ones_pair_only_together)"""
    cfg = leg_config(3)
    rng = np.random.default_rng(9)
    state = with_fields(tracked_legs(cfg, (2.0, 0.35), (2.0, -0.35)),
                        reported_scans=np.array([4, 3]), reported_hits=np.array([4, 3]))
    reported = []
    for k in range(16):
        gap = 0.7 if k < 10 else 0.35
        state, est, diag = filter_step(state, legs(rng, 0.1 * (k + 1), (2.0, 0.0), (1.0, 0.0),
                                                   gap=gap), 0.1, cfg)
        reported.append((est.label.tolist(), diag.joined_labels))
    joins = [k for k, (_, joined) in enumerate(reported) if joined]
    assert len(joins) == 1 and joins[0] >= 12          # three scans at 0.35 m, from 10 on
    assert all(labels == [3, 5] for labels, _ in reported[:joins[0]])
    assert all(labels == [3] for labels, _ in reported[joins[0]:])


@pytest.mark.parametrize('mode', ['cphd', 'phd'])
def test_a_join_thins_the_cardinality_by_the_junior_weight_it_drops(mode):
    """Two parts of weights 0.9 and 0.6 joined into one of 0.9: in CPHD mode the
    cardinality pmf loses the 0.6 dropped (cphd.thin_cardinality, checked against
    enumeration above), in PHD mode there is none to thin."""
    from extended_tracker.tracks.estimates import Estimates
    from extended_tracker.tracks.extract import extract
    from extended_tracker.tracks.pairs import join_pairs

    cfg = leg_config(3, mode)
    state = tracked_legs(cfg, (2.0, 0.175), (2.0, -0.175))
    log_card = np.log(np.array([0.1, 0.3, 0.6] + [0.0] * (cfg.model.n_max - 2)) + 1e-300)
    state = with_fields(state, mixture=replace(state.filter.mixture, w=np.array([0.9, 0.6])),
                        log_card=log_card, pairs=np.array([[3, 5]]), pair_runs=np.array([2]))
    est = extract(replace(state.filter,
                          log_card=np.log(np.eye(cfg.model.n_max + 1)[2] + 1e-300)), cfg)
    assert isinstance(est, Estimates) and est.label.tolist() == [3, 5]
    out, _, est, joined, _ = join_pairs(state.filter, state.tracks, est, cfg)
    assert joined.tolist() == [5] and est.label.tolist() == [3]
    assert out.mixture.label.tolist() == [3] and out.mixture.w.tolist() == [0.9]
    want = thin_cardinality(log_card, 0.6) if mode == 'cphd' else log_card
    np.testing.assert_allclose(np.exp(out.log_card), np.exp(want), atol=1e-12)


def _parts(labels, xs, semis):
    """Reports of ``labels`` at (x, 0), at rest, round with semi-axes ``semis``."""
    from mixtures import estimates

    est = estimates(list(labels), np.column_stack([xs, np.zeros(len(xs))]))
    est.X[:] = np.array([s ** 2 * np.eye(2) for s in semis])
    return est


def test_a_pair_needs_one_part_sized_report_and_pairs_go_nearest_first():
    """
    ``join_pairs`` (pair_semi_axis 0.3 m, pair_distance 0.6 m): a leg-sized report
    beside a walker-sized one (0.45 m) is a candidate pair, two walker-sized ones are not;
    three leg-sized reports in a row (0.3 m, then 0.2 m apart) pair the nearest two,
    one to one.
    """
    from extended_tracker.tracks.pairs import join_pairs

    cfg = leg_config(3)
    filt = FilterState.initial(cfg)
    record = TrackRecord(reported=np.array([3, 5, 7]), reported_scans=np.array([9, 9, 9]),
                         reported_travel=np.zeros(3))
    forming = [join_pairs(filt, record, _parts([3, 5], [0.0, 0.4], semis), cfg)[1].pairs.tolist()
               for semis in ((0.45, 0.1), (0.45, 0.45))]
    assert forming == [[[3, 5]], []]
    out = join_pairs(filt, record, _parts([3, 5, 7], [0.0, 0.3, 0.5], (0.1, 0.1, 0.1)), cfg)[1]
    assert out.pairs.tolist() == [[5, 7]] and out.pair_runs.tolist() == [1]
    # within pair_distance includes it: two legs exactly 0.6 m apart are a pair
    out = join_pairs(filt, record, _parts([3, 5], [0.0, 0.6], (0.1, 0.1)), cfg)[1]
    assert out.pairs.tolist() == [[3, 5]]


def test_a_part_returns_a_legs_width_where_a_cell_updated_it():
    """Two reports whose extents are part-sized (0.22 m), 0.55 m apart and alike in
    velocity: people side by side at body height, whose cells this scan are 0.4 m wide,
    are no pair; with one cell a leg's width (0.1 m) they are; a report no cell updated
    this scan is judged by its extent alone."""
    from extended_tracker.tracks.pairs import join_pairs, PART_WIDTH

    cfg = leg_config(3)
    filt = FilterState.initial(cfg)
    record = TrackRecord(reported=np.array([3, 5]), reported_scans=np.array([2, 2]),
                         reported_travel=np.zeros(2))
    parts = _parts([3, 5], [0.0, 0.55], (0.22, 0.22))

    def forming(widths):
        return join_pairs(filt, record, parts, cfg, widths)[1].pairs.tolist()

    assert 0.1 < PART_WIDTH < 0.4
    assert forming({3: 0.4, 5: 0.4}) == []
    assert forming({3: 0.4, 5: 0.1}) == [[3, 5]]
    assert forming({3: 0.4}) == [[3, 5]]
    assert forming(None) == [[3, 5]]


def side_by_side_ids(at_legs, gap=0.6, seconds=5.0):
    """The ids shown while two people walk side by side, ``gap`` m between their paths,
    away from a scanner (the defaults), from their second second on."""
    from extended_tracker.pipeline import PipelineState, step
    from extended_tracker.sim.laser import LaserSpec, Scene, SimObject, simulate
    from extended_tracker.sim.leg_scenes import at_leg_height

    scene = Scene(objects=(SimObject((1.0, 0.0), (1.2, 0.0)),
                           SimObject((1.0, gap), (1.2, 0.0))), laser=LaserSpec())
    scene = at_leg_height(scene) if at_legs else scene
    cfg, shown = from_dict({}), []
    state = PipelineState.initial(cfg)
    for k, (scan, _) in enumerate(simulate(scene, seconds, seed=1)):
        state, res = step(state, scan, cfg)
        if k >= 10:
            shown.append(sorted(res.estimates.label.tolist()))
    return shown


@pytest.mark.parametrize('at_legs', [False, True])
def test_two_people_side_by_side_stay_two_at_either_height(at_legs):
    """With the defaults, two people walking side by side 0.6 m apart are two ids in
    every scan: at body height each is too wide a return to be a leg (their pair was
    joined into one id), at leg height their four legs pair two by two."""
    shown = side_by_side_ids(at_legs)
    assert all(len(ids) == 2 for ids in shown)
    assert len({lab for ids in shown for lab in ids}) == 2


def test_a_pair_forming_keeps_its_partner_when_a_nearer_fragment_is_born():
    """Pairs go nearest first, but a pair already forming goes before them all: on the
    leg_tracker demo a walker near the scanner had fragments born beside its legs, each
    nearer than the other leg for a scan, and the legs' pair run broke every time."""
    from extended_tracker.tracks.pairs import join_pairs

    cfg = leg_config(3)
    filt = FilterState.initial(cfg)
    parts = _parts([3, 5, 7], [0.0, 0.45, 0.25], (0.1, 0.1, 0.1))    # 7: a fragment
    record = TrackRecord(reported=np.array([3, 5, 7]), reported_scans=np.array([9, 5, 1]),
                         reported_travel=np.zeros(3))
    assert join_pairs(filt, record, parts, cfg)[1].pairs.tolist() == [[5, 7]]
    forming = replace(record, pairs=np.array([[3, 5]]), pair_runs=np.array([1]))
    out = join_pairs(filt, forming, parts, cfg)[1]
    assert out.pairs.tolist() == [[3, 5]] and out.pair_runs.tolist() == [2]


@pytest.mark.parametrize('scans, senior, junior', [((9, 9), 3, 5), ((4, 9), 5, 3),
                                                   ((9, 4), 3, 5)])
def test_a_pair_joins_under_the_label_reported_longer_then_the_smaller(scans, senior, junior):
    """The senior of a pair ready to join is the label reported in more scans in a row;
    between equals, the smaller label. The junior leaves the estimates and the mixture."""
    from extended_tracker.tracks.pairs import join_pairs

    from mixtures import pedestrians, reported

    cfg = leg_config(3)
    filt = replace(FilterState.initial(cfg),
                   mixture=pedestrians([(3, 0.9, 0.0, 0.0), (5, 0.8, 0.3, 0.0)]))
    record = reported(TrackRecord(pairs=np.array([[3, 5]]), pair_runs=np.array([2])),
                      [3, 5], list(scans), [[0.0, 0.0], [0.3, 0.0]])
    out, out_record, est, joined, _ = join_pairs(filt, record,
                                                 _parts([3, 5], [0.0, 0.3], (0.1, 0.1)), cfg)
    assert joined.tolist() == [junior] and est.label.tolist() == [senior]
    assert out.mixture.label.tolist() == [senior] and out_record.reported.tolist() == [senior]
