"""
Ids do not jump: a label extracted farther from where it was last shown than
``extraction.max_speed`` allows is a new object and gets a new id.

The rule (``identity.relabel_jumps``): last shown at ``p``, ``t`` seconds ago, now at ``q``;
``|q - p| > max_speed * t + jump_slack`` relabels.
"""

import numpy as np

from extended_tracker.config import from_dict
from extended_tracker.filter.mixture import Mixture
from extended_tracker.filter.state import FilterState
from extended_tracker.tracker import filter_step, TrackerState
from extended_tracker.tracks.identity import relabel_jumps, remember_shown
from extended_tracker.tracks.record import TrackRecord

from mixtures import estimates, pedestrians as mixture


def test_the_reach_is_max_speed_times_time_since_shown_plus_slack():
    cfg = from_dict({'extraction': {'max_speed': 3.0, 'jump_slack': 1.0, 'max_accel': 0.0}})
    # labels 4 and 9 were last shown at the origin, 0.5 s before the previous scan
    old = TrackRecord(shown=np.array([4, 9]),
                      shown_pos=np.zeros((2, 2)), shown_vel=np.zeros((2, 2)),
                      shown_elapsed=np.array([0.5, 0.5]))
    mix = mixture([(4, 0.9, 2.7, 0.0), (4, 0.1, 2.6, 0.1), (7, 1.0, 9.0, 9.0),
                   (9, 1.0, 0.0, 2.9)])
    new = FilterState(mix, np.zeros(1), 12)
    # reach 3 m/s * (0.5 + 0.1) s + 1 m = 2.8 m: label 9 at 2.9 m has jumped, label 4 at
    # 2.7 m has not; label 7 was never shown, so it has nothing to jump from
    est = estimates([4, 7, 9], [[2.7, 0.0], [9.0, 9.0], [0.0, 2.9]])
    out, out_est, n = relabel_jumps(old, new, est, cfg, 0.1)
    assert n == 1
    assert out_est.label.tolist() == [4, 7, 12]
    assert out.mixture.label.tolist() == [4, 4, 7, 12]
    assert out.next_label == 13
    # positions and weights are the filter's, untouched
    assert np.array_equal(out.mixture.m, mix.m) and np.array_equal(out.mixture.w, mix.w)
    assert np.array_equal(out_est.m, est.m)
    # just inside the reach: nothing changes
    est = estimates([9], [[0.0, 2.79]])
    out, out_est, n = relabel_jumps(old, new, est, cfg, 0.1)
    assert n == 0 and out is new and out_est is est


def test_a_report_beyond_what_max_accel_allows_from_the_shown_velocity_is_a_new_object():
    cfg = from_dict({'extraction': {'max_speed': 15.0, 'jump_slack': 1.0, 'max_accel': 10.0}})
    # label 4 stood still and label 9 walked at 1.5 m/s along x, both last shown at the
    # origin 0.3 s before the previous scan: t = 0.4 s, allowance 10 * 0.4^2 / 2 + 1 = 1.8 m
    old = TrackRecord(shown=np.array([4, 9]),
                      shown_pos=np.zeros((2, 2)), shown_vel=np.array([[0.0, 0.0], [1.5, 0.0]]),
                      shown_elapsed=np.array([0.3, 0.3]))
    new = FilterState(mixture([(4, 1.0, 3.0, 0.0), (9, 1.0, 2.3, 0.0)]), np.zeros(1), 20)
    # 4 is 3 m from rest (within 15 m/s * 0.4 s + 1 m = 7 m, but 3 > 1.8); 9 is 2.3 m from
    # the origin but only 1.7 m from where 1.5 m/s carried it (0.6 m): both within reach of
    # the speed limit, only 4 beyond the acceleration's
    out, est, n = relabel_jumps(old, new, estimates([4, 9], [[3.0, 0.0], [2.3, 0.0]]), cfg, 0.1)
    assert n == 1 and est.label.tolist() == [9, 20]
    assert out.mixture.label.tolist() == [20, 9]
    # just inside the allowance from rest: kept, just outside: a new object; and
    # max_accel 0 switches the check off
    est = estimates([4], [[1.79, 0.0]])
    assert relabel_jumps(old, new, est, cfg, 0.1)[2] == 0
    assert relabel_jumps(old, new, estimates([4], [[1.81, 0.0]]), cfg, 0.1)[2] == 1
    off = from_dict({'extraction': {'max_speed': 15.0, 'jump_slack': 1.0, 'max_accel': 0.0}})
    assert relabel_jumps(old, new, estimates([4], [[3.0, 0.0]]), off, 0.1)[2] == 0


def test_relabelled_ids_are_never_reused_and_each_gets_its_own():
    cfg = from_dict({'extraction': {'max_speed': 1.0, 'jump_slack': 0.0}})
    old = TrackRecord(shown=np.array([2, 5]),
                      shown_pos=np.zeros((2, 2)), shown_vel=np.zeros((2, 2)),
                      shown_elapsed=np.zeros(2))
    new = FilterState(mixture([(2, 1.0, 5.0, 0.0), (5, 1.0, 0.0, 5.0)]), np.zeros(1), 30)
    out, est, n = relabel_jumps(old, new, estimates([2, 5], [[5.0, 0.0], [0.0, 5.0]]), cfg, 0.1)
    assert n == 2 and est.label.tolist() == [30, 31]
    assert out.mixture.label.tolist() == [30, 31] and out.next_label == 32


def test_shown_positions_age_and_dead_labels_are_forgotten():
    old = TrackRecord(shown=np.array([1, 3, 8]),
                      shown_pos=np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]),
                      shown_vel=np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]]),
                      shown_elapsed=np.array([0.3, 0.0, 0.1]))
    # label 8 is no longer in the mixture; 3 is shown again; 6 is shown for the first time
    new = FilterState(mixture([(1, 1.0, 0.0, 0.0), (3, 1.0, 1.5, 1.0), (6, 1.0, 4.0, 4.0)]),
                      np.zeros(1))
    shown = estimates([3, 6], [[1.5, 1.0], [4.0, 4.0]])
    shown.m[:, 2:] = [[0.5, 0.0], [0.0, -0.5]]
    out = remember_shown(old, new, shown, 0.1, 1)
    assert out.shown.tolist() == [1, 3, 6]
    np.testing.assert_allclose(out.shown_pos, [[0.0, 0.0], [1.5, 1.0], [4.0, 4.0]])
    np.testing.assert_allclose(out.shown_vel, [[1.0, 0.0], [0.5, 0.0], [0.0, -0.5]])
    np.testing.assert_allclose(out.shown_elapsed, [0.4, 0.0, 0.0])
    # within the handover time a dead label is remembered (0.2 s ago), then forgotten
    out = remember_shown(old, new, shown, 0.1, 1, handover_time=0.2)
    assert out.shown.tolist() == [1, 3, 6, 8]
    np.testing.assert_allclose(out.shown_elapsed, [0.4, 0.0, 0.0, 0.2])
    assert remember_shown(out, new, shown, 0.1, 1, handover_time=0.2).shown.tolist() == [1, 3, 6]
    # a label joined into another (a leg into its walker) is part of that object, not
    # lost: forgotten at once, however recently shown
    joined = remember_shown(old, new, shown, 0.1, 1, handover_time=0.2,
                            joined=np.array([1, 8]))
    assert joined.shown.tolist() == [3, 6]


def test_the_label_clock_keeps_the_counter_of_each_scan_within_the_handover_time():
    """At the start of each scan of the last ``handover_time`` seconds, the next label
    then: a reading that ages past the window is dropped, this scan's is added."""
    old = TrackRecord(label_clock=((0.95, 4), (0.5, 8), (0.1, 10)))
    new = FilterState(Mixture.empty(), np.zeros(1))
    out = remember_shown(old, new, estimates([], np.zeros((0, 2))), 0.1, 12,
                         handover_time=1.0)
    np.testing.assert_allclose([ago for ago, _ in out.label_clock], [0.6, 0.2, 0.0])
    assert [lab for _, lab in out.label_clock] == [8, 10, 12]


def _occlusion_then_newcomer(max_speed, newcomer_y, gap=15, seed=0, max_accel=10.0):
    """
    A walker at 1 m/s along y = 0 for 3 s, unseen for ``gap`` scans (p_D 0.05: behind
    something), then returns only from a person standing at (6, newcomer_y), or (when
    ``newcomer_y`` is None) from the walker again, further along its line.

    Returns, per scan, the reported labels and positions.
    """
    cfg = from_dict({'extraction': {'max_speed': max_speed, 'max_accel': max_accel}})
    rng = np.random.default_rng(seed)
    state = TrackerState.initial(cfg)
    out = []
    for k in range(60):
        p_d = 0.9
        if k < 30:
            centre = (3.0 + 0.1 * k, 0.0)
        elif k < 30 + gap:
            centre, p_d = None, 0.05
        else:
            centre = (6.0, newcomer_y) if newcomer_y is not None else (3.0 + 0.1 * k, 0.0)
        pts = np.zeros((0, 2)) if centre is None else centre + rng.normal(0, 0.12, (10, 2))
        # 500 m^2 of clutter area: the birth density is low enough that the coasting
        # track's wide prediction outbids it for the newcomer (as seen on real scans)
        state, est, diag = filter_step(state, pts, 0.1, cfg, p_d=p_d, clutter_area=500.0)
        out.append((est.label.tolist(), est.m[:, :2].copy(), diag.relabelled))
    return out


def test_a_coasting_track_does_not_hand_its_id_to_a_newcomer():
    # the premise: with neither limit, the walker's id reappears on the newcomer 2.5 m
    # off its line (the CV model's white acceleration lets its prediction spread there)
    free = _occlusion_then_newcomer(1000.0, 2.5, max_accel=0.0)
    assert free[29][0] == [1]
    assert any(lab == [1] and m[0, 1] > 2.0 for lab, m, _ in free[30:])
    # at walking speed, or at the default acceleration, the newcomer is a new object: a
    # new id once confirmed
    for limited in (_occlusion_then_newcomer(3.0, 2.5, max_accel=0.0),
                    _occlusion_then_newcomer(1000.0, 2.5)):
        assert sum(r for _, _, r in limited) == 1
        for lab, m, _ in limited[30:]:
            for label, (_, y) in zip(lab, m):
                if y > 2.0:
                    assert label > 1
        assert limited[-1][0] and limited[-1][0][0] > 1


def test_a_walker_back_on_its_path_keeps_its_id():
    runs = _occlusion_then_newcomer(3.0, None, gap=8)
    assert sum(r for _, _, r in runs) == 0
    assert runs[29][0] == [1] and runs[-1][0] == [1]


def test_relabelled_estimates_stay_in_label_order_for_the_shown_record():
    # confirm_scans 1: a relabelled id is shown in the same scan. The fresh label is the
    # largest, so a jump of label 4 beside label 9 must not leave the estimates as [13, 9]:
    # the shown record looks labels up in them as a sorted array and would keep label 9
    # twice, once at its stale position.
    cfg = from_dict({'extraction': {'max_speed': 1.0, 'jump_slack': 0.0, 'confirm_scans': 1}})
    old = TrackRecord(shown=np.array([4, 9]),
                      shown_pos=np.array([[0.0, 0.0], [0.0, 3.0]]), shown_vel=np.zeros((2, 2)),
                      shown_elapsed=np.zeros(2))
    new = FilterState(mixture([(4, 1.0, 5.0, 0.0), (9, 1.0, 0.0, 3.05)]), np.zeros(1), 13)
    out, est, n = relabel_jumps(old, new, estimates([4, 9], [[5.0, 0.0], [0.0, 3.05]]), cfg, 0.1)
    assert n == 1
    assert est.label.tolist() == [9, 13]
    np.testing.assert_allclose(est.m[:, :2], [[0.0, 3.05], [5.0, 0.0]])
    shown = remember_shown(old, out, est, 0.1, 1)
    assert shown.shown.tolist() == [9, 13]
    np.testing.assert_allclose(shown.shown_pos, [[0.0, 3.05], [5.0, 0.0]])
