"""The age and time since detection of each shown id, against a reference loop over the
step results (first stamp each label is shown at, last stamp returns updated it at)."""
import numpy as np

from extended_tracker.config import from_dict
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.report.messages import tracks_data
from extended_tracker.sim.laser import simulate, tutorial_scene


def test_ages_and_times_since_detection_follow_the_stamps():
    cfg = from_dict({'background': {'enabled': False}})
    state = PipelineState.initial(cfg)
    first, detected, shown_before = {}, {}, set()
    coasted = 0
    for scan, _ in simulate(tutorial_scene(), 8.0, seed=1):
        state, r = step(state, scan, cfg)
        e, now = r.estimates, r.stamp_ns
        for j, lab in enumerate(e.label.tolist()):
            if lab not in shown_before:                  # new, or back after a gap
                first[lab] = now
            if e.num_detections[j] > 0 or lab not in shown_before:
                detected[lab] = now
            assert r.age[j] == (now - first[lab]) * 1e-9
            assert r.since_detected[j] == (now - detected[lab]) * 1e-9
            coasted += r.since_detected[j] > 0
        shown_before = set(e.label.tolist())
        msg = tracks_data(r, cfg)
        assert [o['age'] for o in msg['objects']] == r.age.tolist()
        for o, P in zip(msg['objects'], e.P):
            assert np.array_equal(o['velocity_covariance'], P[2:, 2:].ravel())
    assert coasted > 5                    # the walker hidden behind the stander coasts
    assert max(r.age) > 6.0
