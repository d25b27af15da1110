"""
Lost ids pass to young objects where the lost object would be (``identity.hand_over``).

A label shown less than ``extraction.handover_time`` ago and not extracted now is lost; a
label created less than ``handover_time`` ago and extracted now is young. A young label
within ``extraction.handover_distance`` of where the lost one would be (last shown
position plus velocity times the time since) takes the lost id.
"""

from dataclasses import replace

import numpy as np

from extended_tracker.config import from_dict
from extended_tracker.filter.state import FilterState
from extended_tracker.tracker import filter_step, TrackerState
from extended_tracker.tracks.identity import hand_over
from extended_tracker.tracks.record import TrackRecord

from mixtures import estimates, pedestrians as mixture


def lost_state(shown, pos, vel=None, elapsed=None, reported=(), reported_scans=(),
               recent_from=9, clock=None):
    """The record of labels ``shown`` last shown at ``pos``; labels from ``recent_from`` on
    are young (or as the label ``clock`` says). The label counter stands at 12."""
    k = len(shown)
    return TrackRecord(
        reported=np.array(reported, dtype=np.int64),
        reported_scans=np.array(reported_scans, dtype=np.int64),
        reported_origin=np.zeros((len(reported), 2)), reported_travel=np.zeros(len(reported)),
        reported_size=np.zeros(len(reported)),
        reported_hits=np.array(reported_scans, dtype=np.int64),
        shown=np.array(shown, dtype=np.int64), shown_pos=np.array(pos, dtype=float),
        shown_vel=np.zeros((k, 2)) if vel is None else np.array(vel, dtype=float),
        shown_elapsed=np.zeros(k) if elapsed is None else np.array(elapsed, dtype=float),
        label_clock=((0.5, recent_from),) if clock is None else clock)


CFG = from_dict({'extraction': {'handover_time': 1.0, 'handover_distance': 0.8}})


def test_a_young_label_where_the_lost_one_would_be_takes_its_id_and_the_labels_swap():
    # label 5 was shown 0.4 s before the last scan at the origin walking at 1 m/s along
    # x: it would be at (0.5, 0) now. Young label 9 is at (0.9, 0.3), 0.5 m from there.
    old = lost_state([5], [[0.0, 0.0]], vel=[[1.0, 0.0]], elapsed=[0.4],
                     reported=[9], reported_scans=[2])
    new = FilterState(mixture([(5, 0.05, 0.5, 0.0), (9, 0.7, 0.9, 0.3), (9, 0.3, 0.95, 0.3)]),
                      np.zeros(1), 12)
    out, est, record, n = hand_over(old, new, estimates([9], [[0.9, 0.3]]), CFG, 0.1, 12)
    assert n == 1
    assert est.label.tolist() == [5]
    # the young object's components carry the old id, the fading ones the young label
    assert out.mixture.label.tolist() == [9, 5, 5]
    assert np.array_equal(out.mixture.w, new.mixture.w)
    # 5 was not extracted in the last scan: 9's count of 2 scans goes on under 5
    assert record.reported.tolist() == [5] and record.reported_scans.tolist() == [2]


def test_an_id_extracted_in_the_last_scan_keeps_its_own_report_count():
    old = lost_state([5], [[0.0, 0.0]], reported=[5, 9], reported_scans=[40, 1])
    new = FilterState(mixture([(5, 0.1, 0.0, 0.0), (9, 1.0, 0.4, 0.0)]), np.zeros(1), 12)
    _, est, record, n = hand_over(old, new, estimates([9], [[0.4, 0.0]]), CFG, 0.1, 12)
    assert n == 1 and est.label.tolist() == [5]
    assert record.reported.tolist() == [5, 9] and record.reported_scans.tolist() == [40, 1]


def test_an_established_label_never_takes_a_lost_id():
    # label 7 is right where lost label 5 would be, but it is older than the window
    old = lost_state([5, 7], [[0.0, 0.0], [0.3, 0.0]])
    new = FilterState(mixture([(5, 0.1, 0.0, 0.0), (7, 1.0, 0.3, 0.0)]), np.zeros(1), 12)
    est = estimates([7], [[0.3, 0.0]])
    out, out_est, _, n = hand_over(old, new, est, CFG, 0.1, 12)
    assert n == 0 and out is new and out_est is est
    # the same object under a label created in the window does take it
    _, out_est, _, n = hand_over(lost_state([5, 7], [[0.0, 0.0], [0.3, 0.0]], recent_from=7),
                                 new, est, CFG, 0.1, 12)
    assert n == 1 and out_est.label.tolist() == [5]
    # the counter's older readings are beyond the window: 7, created 1.5 s ago, is not
    # young, whatever was created in the window (from 9 on)
    older = lost_state([5, 7], [[0.0, 0.0], [0.3, 0.0]], clock=((1.5, 3), (0.5, 9)))
    assert hand_over(older, new, est, CFG, 0.1, 12)[3] == 0


def test_an_id_passes_only_to_a_newer_label():
    """
    Two young labels on one object: each scan the one extracted took the id of the other,
    shown the scan before, and the report traded ids every scan for as long as both were
    young (the Freiburg recording, 26 scans in a row after the background warm-up). An
    id passes only to a label created after it, so the object ends under the older one.
    """
    both_young = lost_state([5, 7], [[0.0, 0.0], [0.05, 0.0]], recent_from=5)
    under_5 = FilterState(mixture([(5, 1.0, 0.02, 0.0), (7, 0.05, 0.05, 0.0)]), np.zeros(1), 12)
    est = estimates([5], [[0.02, 0.0]])
    out, out_est, _, n = hand_over(both_young, under_5, est, CFG, 0.1, 12)
    assert n == 0 and out is under_5 and out_est is est
    under_7 = FilterState(mixture([(5, 0.05, 0.0, 0.0), (7, 1.0, 0.02, 0.0)]), np.zeros(1), 12)
    _, out_est, _, n = hand_over(both_young, under_7, estimates([7], [[0.02, 0.0]]), CFG, 0.1, 12)
    assert n == 1 and out_est.label.tolist() == [5]


def test_too_far_too_late_or_switched_off_means_no_handover():
    new = FilterState(mixture([(5, 0.1, 0.0, 0.0), (9, 1.0, 0.85, 0.0)]), np.zeros(1), 12)
    est = estimates([9], [[0.85, 0.0]])
    # 0.85 m from where 5 would be (it stood still): beyond 0.8 m
    assert hand_over(lost_state([5], [[0.0, 0.0]]), new, est, CFG, 0.1, 12)[3] == 0
    # walking at 1 m/s towards it, 0.4 s + 0.1 s ago: it would be at 0.5 m, 0.35 m away
    moving = lost_state([5], [[0.0, 0.0]], vel=[[1.0, 0.0]], elapsed=[0.4])
    assert hand_over(moving, new, est, CFG, 0.1, 12)[3] == 1
    # shown 1 s before the last scan: lost for longer than the window
    late = lost_state([5], [[0.0, 0.0]], vel=[[1.0, 0.0]], elapsed=[1.0])
    assert hand_over(late, new, est, CFG, 0.1, 12)[3] == 0
    off = from_dict({'extraction': {'handover_time': 0.0}})
    assert hand_over(moving, new, est, off, 0.1, 12)[3] == 0
    # the speed limit has the last word: 0.85 m in 0.5 s is more than 0.5 m/s allows
    slow = from_dict({'extraction': {'max_speed': 0.5, 'jump_slack': 0.0}})
    assert hand_over(moving, new, est, slow, 0.1, 12)[3] == 0
    for max_speed, passes in ((1.6, 0), (1.8, 1)):           # 0.8 and 0.9 m in 0.5 s
        cfg = from_dict({'extraction': {'max_speed': max_speed, 'jump_slack': 0.0}})
        assert hand_over(moving, new, est, cfg, 0.1, 12)[3] == passes, max_speed


def test_nearest_pairs_first_one_to_one_and_estimates_stay_in_label_order():
    old = lost_state([5, 6], [[0.0, 0.0], [1.0, 0.0]])
    new = FilterState(mixture([(5, 0.1, 0.0, 0.0), (6, 0.1, 1.0, 0.0), (9, 1.0, 0.3, 0.0),
                               (10, 1.0, 0.1, 0.0), (11, 1.0, 0.5, 0.0)]),
                      np.zeros(1), 12)
    # pairs within 0.8 m, nearest first: 10-5 (0.1), 9-5 (0.3), 11-5 and 11-6 (0.5), 9-6
    # (0.7). 10 takes 5; 5 is then taken, so 11 takes 6 and 9 keeps its own label.
    est = estimates([9, 10, 11], [[0.3, 0.0], [0.1, 0.0], [0.5, 0.0]])
    out, est, _, n = hand_over(old, new, est, CFG, 0.1, 12)
    assert n == 2
    assert est.label.tolist() == [5, 6, 9]
    np.testing.assert_allclose(est.m[:, 0], [0.1, 0.5, 0.3])
    assert out.mixture.label.tolist() == [10, 11, 9, 5, 6]


def _walker(handover_time, step_aside, gap=0, seed=0):
    """
    Eight returns around a walker at 1 m/s along y = 1 for 2 s; then it is unseen for
    ``gap`` scans and goes on ``step_aside`` m to the side (as a leg-height walker's
    track jumps from one leg to the other). Returns the reported labels of each scan.
    """
    cfg = from_dict({'extraction': {'handover_time': handover_time}})
    rng = np.random.default_rng(seed)
    state = TrackerState.initial(cfg)
    out = []
    for k in range(40):
        centre = np.array([2.0 + 0.1 * k, 1.0 + (step_aside if k >= 20 else 0.0)])
        a = rng.uniform(0.0, 2.0 * np.pi, 8)
        pts = centre + 0.15 * np.c_[np.cos(a), np.sin(a)] + rng.normal(0.0, 0.02, (8, 2))
        if 20 <= k < 20 + gap:
            pts = np.zeros((0, 2))
        state, est, diag = filter_step(state, pts, 0.1, cfg, clutter_area=50.0)
        out.append((est.label.tolist(), diag.handed_over))
    return out


def test_a_walker_whose_returns_step_aside_keeps_its_id():
    # the premise: without handover the track fades and a second id follows the walker
    plain = _walker(0.0, 0.6)
    assert plain[19][0] == [1] and plain[-1][0] == [2]
    kept = _walker(1.0, 0.6)
    assert all(labels == [1] for labels, _ in kept[2:])
    assert sum(n for _, n in kept) == 1
    # unseen for 0.5 s first: the id comes back with the walker
    gap = _walker(1.0, 0.6, gap=5)
    assert gap[19][0] == [1] and gap[-1][0] == [1]


def test_a_newcomer_too_far_or_too_late_gets_its_own_id():
    far = _walker(1.0, 1.5)
    assert far[19][0] == [1] and far[-1][0] == [2]
    assert sum(n for _, n in far) == 0
    late = _walker(1.0, 0.6, gap=12)
    assert late[19][0] == [1] and late[-1][0] == [2]
    assert sum(n for _, n in late) == 0


def test_a_lost_movers_id_goes_before_a_lost_settled_ones():
    """
    A walker (label 3, moving) comes beside an object tracked where it stood since
    start-up (label 2, settled: reported SETTLED_SCANS scans, never moved). One cell holds
    both, a young label (9) takes it, both are lost; 9 stands nearer the object. The
    walker's id goes to 9, and the object's stays free for its own track to take back
    (the MiR recording: nearest first took the object's id away with the walker).
    """
    from extended_tracker.tracks.record import SETTLED_SCANS

    def record(travel):
        r = lost_state([2, 3], [[0.0, 0.0], [0.7, 0.0]], reported=[2, 3],
                       reported_scans=[SETTLED_SCANS, SETTLED_SCANS])
        return replace(r, reported_travel=np.array(travel, dtype=float))

    new = FilterState(mixture([(2, 0.1, 0.0, 0.0), (3, 0.1, 0.7, 0.0), (9, 1.0, 0.3, 0.0)]),
                      np.zeros(1), 12)
    est = estimates([9], [[0.3, 0.0]])
    moved = CFG.background.moved_distance
    _, out_est, _, n = hand_over(record([0.0, 2 * moved]), new, est, CFG, 0.1, 12)
    assert n == 1 and out_est.label.tolist() == [3]
    # both settled, or both movers: the nearest lost id, as before
    for travel in ([0.0, 0.0], [2 * moved, 2 * moved]):
        _, out_est, _, n = hand_over(record(travel), new, est, CFG, 0.1, 12)
        assert n == 1 and out_est.label.tolist() == [2]
    # the object settled but not in the last report (lost for longer): a mover like any
    r = replace(lost_state([2, 3], [[0.0, 0.0], [0.7, 0.0]], reported=[3],
                           reported_scans=[SETTLED_SCANS]), reported_travel=np.array([2 * moved]))
    _, out_est, _, n = hand_over(r, new, est, CFG, 0.1, 12)
    assert n == 1 and out_est.label.tolist() == [2]
