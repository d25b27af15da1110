"""
Several scanners placed in one fixed frame feed one tracker: each with its own shadows,
its own background on its own clock, and the others' fields of view keeping what it
cannot see.
"""
import math

import numpy as np
import pytest

from extended_tracker.config import from_dict
from extended_tracker.evaluation.metrics import score_sequence
from extended_tracker.frames.pose import Pose2
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.scanners import View
from extended_tracker.sim.two_scanners import two_scanner_scans

CFG = from_dict({'model': {'clutter_density': 'beam'}})


def run(only=None):
    """The two-scanner scene through the pipeline (only one scanner's scans with
    ``only``): the results, the GOSPA score and the ids on the circling person."""
    state, results, truth_seq, est_seq, circling = PipelineState.initial(CFG), [], [], [], []
    for scan, truth, place in two_scanner_scans(12.0, 8):
        if only and scan.header.frame_id != only:
            continue
        state, res = step(state, scan, CFG, place=place)
        results.append(res)
        e = res.estimates
        truth_seq.append(([o.id for o in truth], np.array([o.centre for o in truth]),
                          np.array([o.extent for o in truth])))
        est_seq.append((e.label.tolist(), e.m[:, :2], e.X))
        person = next(o for o in truth if o.kind == 'circling')
        if len(e) and np.min(np.linalg.norm(e.m[:, :2] - person.centre, axis=1)) < 0.7:
            circling.append(int(e.label[np.argmin(np.linalg.norm(e.m[:, :2] - person.centre,
                                                                 axis=1))]))
    score, _ = score_sequence(truth_seq, est_seq, 2.0, 2.0)
    return state, results, score, circling


@pytest.fixture(scope='module')
def both():
    return run()


def test_a_person_circling_the_robot_keeps_one_id_across_the_seams(both):
    _, results, score, circling = both
    assert len(circling) > 0.85 * len(results) and len(set(circling)) == 1
    assert score.id_switches == 0 and score.false_mean == 0.0


def test_two_scanners_track_better_than_either_alone(both):
    """The oracle is each scanner alone: together they score better than either, and
    keep the circling person in scans where either alone has lost it behind its back."""
    _, results, together, circling = both
    for only in ('front_laser', 'rear_laser'):
        _, alone_results, alone, alone_circling = run(only)
        assert together.gospa_mean < alone.gospa_mean - 0.3
        assert len(alone_circling) / len(alone_results) < len(circling) / len(results) - 0.15


def test_each_scanner_keeps_its_own_background_and_pose(both):
    """Scans of the two scanners alternate without a layout change or a restart; each
    scanner's per-beam background is its own (its beams), learned on its own clock."""
    state, results, _, _ = both
    assert not [r.event for r in results if r.event]
    assert state.scanner in ('front_laser', 'rear_laser') and len(state.others) == 1
    (other,) = state.others.values()
    for bg in (state.background, other.background):
        assert len(bg.angles) == 541 and np.isfinite(bg.background).mean() > 0.9
    assert {r.frame_id for r in results} == {'base_link'}


def test_a_view_sees_its_sector_out_to_its_range():
    view = View(Pose2(1.0, 0.0, math.pi / 2), -0.75 * math.pi, 0.75 * math.pi, 5.0, False)
    pts = np.array([[1.0, 3.0],        # ahead
                    [1.0, -0.5],       # right behind it: outside 270 deg
                    [1.0, 7.0],        # ahead, beyond range
                    [-2.0, 0.0]])      # to its left
    assert view.sees(pts).tolist() == [True, False, False, True]
    full = View(Pose2(), -math.pi, math.pi, 5.0, True)
    assert full.sees(pts).tolist() == [True, True, False, True]
