"""
Duplicate labels: two labels on one object become one; two objects keep theirs.

The rule (``tracker.fuse_duplicate_labels``): heads within the merge distance of each
other, both ways, and label weights summing to at most ``reduction.fuse_weight``.
"""

from dataclasses import replace

import numpy as np
import pytest

from extended_tracker.config import from_dict
from extended_tracker.filter.state import FilterState
from extended_tracker.tracker import filter_step, TrackerState
from extended_tracker.tracks.labels import fuse_duplicate_labels
from extended_tracker.tracks.record import TrackRecord

from mixtures import pedestrians as mixture

MERGE = 4.0


def weights_by_label(mix):
    return {int(l): round(float(mix.w[mix.label == l].sum()), 6) for l in np.unique(mix.label)}


def test_two_light_labels_on_one_spot_become_the_senior_label():
    mix = mixture([(29, 0.36, 0.56, -1.64), (30, 0.74, 0.55, -1.64), (30, 0.01, 0.60, -1.6)])
    # neither reported yet: the heavier label stays (the older one may have been shown
    # long ago somewhere else, and a light coasting label must not bring its id along)
    out, fused = fuse_duplicate_labels(mix, MERGE, 1.5)
    assert fused == 1
    assert weights_by_label(out) == {30: 1.11}
    # equally heavy too: the older label
    even = mixture([(29, 0.5, 0.56, -1.64), (30, 0.5, 0.55, -1.64)])
    assert weights_by_label(fuse_duplicate_labels(even, MERGE, 1.5)[0]) == {29: 1.0}
    # nothing else changes
    assert np.array_equal(out.m, mix.m) and np.array_equal(out.w, mix.w)
    # the id a user has been shown stays: the label reported in more scans in a row
    out, _ = fuse_duplicate_labels(mix, MERGE, 1.5, np.array([30]), np.array([4]))
    assert weights_by_label(out) == {30: 1.11}
    out, _ = fuse_duplicate_labels(mix, MERGE, 1.5, np.array([7, 29, 30]),
                                    np.array([9, 6, 2]))
    assert weights_by_label(out) == {29: 1.11}


def test_two_tracked_objects_passing_close_keep_their_labels():
    # one unit of weight each: two objects, even where their centres nearly meet
    mix = mixture([(1, 1.0, 2.0, 0.0), (2, 0.98, 2.01, 0.0)])
    out, fused = fuse_duplicate_labels(mix, MERGE, 1.5)
    assert fused == 0 and np.array_equal(out.label, mix.label)


def test_light_labels_apart_keep_their_labels():
    # 0.6 m apart: more than the two 0.2 m semi-axes together, the objects do not overlap
    mix = mixture([(1, 0.5, 2.0, 0.0), (2, 0.4, 2.6, 0.0)])
    out, fused = fuse_duplicate_labels(mix, MERGE, 1.5)
    assert fused == 0 and np.array_equal(out.label, mix.label)


def test_the_weight_bound_is_kept_as_labels_are_absorbed_and_zero_disables():
    # heaviest first: 0.7 absorbs 0.5 (1.2); 0.4 would make 1.6 > 1.5 and stays
    mix = mixture([(1, 0.7, 1.0, 1.0), (2, 0.5, 1.0, 1.0), (3, 0.4, 1.0, 1.0)])
    out, fused = fuse_duplicate_labels(mix, MERGE, 1.5)
    assert fused == 1 and weights_by_label(out) == {1: 1.2, 3: 0.4}
    out, fused = fuse_duplicate_labels(mix, MERGE, 0.0)
    assert fused == 0 and np.array_equal(out.label, mix.label)


@pytest.mark.parametrize('fuse', [0.0, 1.5])
def test_one_object_ends_with_one_label(fuse):
    """
    A filter started with the same object under two labels (a birth that came out twice):
    with fusion it reports one id for it, without it two labels follow it.
    """
    cfg = from_dict({'reduction': {'fuse_weight': fuse}})
    rng = np.random.default_rng(3)
    start = mixture([(1, 0.55, 3.0, 0.0), (2, 0.5, 3.02, 0.01)])
    state = TrackerState(replace(FilterState.initial(cfg), mixture=start, next_label=3))
    for _ in range(10):
        pts = np.array([3.0, 0.0]) + rng.normal(0, 0.12, (12, 2))
        state, est, diag = filter_step(state, pts, 0.1, cfg)
    mix = state.filter.mixture
    labels = set(np.unique(mix.label[mix.w > 0.1]).tolist())
    if fuse:
        assert labels == {1}
    else:
        assert labels == {1, 2}


def test_a_shown_id_survives_a_heavier_fresh_label_on_the_same_object():
    """
    A walker's track has faded (0.3) while a fresh label (0.8) took its returns: after the
    step the walker keeps the id it was shown under.
    """
    cfg = from_dict({})
    rng = np.random.default_rng(4)
    filt = replace(FilterState.initial(cfg),
                   mixture=mixture([(7, 0.3, 3.0, 0.0), (12, 0.8, 3.01, 0.0)]), next_label=13)
    record = TrackRecord(reported=np.array([7]), reported_scans=np.array([25]),
                         reported_hits=np.array([25]), reported_origin=np.array([[1.0, 0.0]]),
                         reported_travel=np.array([2.0]), reported_size=np.zeros(1))
    state = TrackerState(filt, record)
    pts = np.array([3.0, 0.0]) + rng.normal(0, 0.12, (12, 2))
    state, est, diag = filter_step(state, pts, 0.1, cfg)
    assert diag.fused_labels == 1
    assert est.label.tolist() == [7]


def test_a_new_labels_birth_cell_does_not_rest_on_last_bits():
    """Of a new label's birth cells the heaviest gives its detections, and weights that tie
    but for their last bits (numpy's exp differs there between CPUs) order by row."""
    from extended_tracker.filter.births import birth_label_cells

    born, bsel = np.array([5, 5, 6]), np.array([0, 2, 1])
    for eps in (1e-12, -1e-12):
        w = np.array([0.3, 0.1, 0.3 * (1.0 + eps)])      # cells 0 and 2 tie to float32
        assert birth_label_cells(born, bsel, w, 5) == [(5, 0), (6, 1)]
    assert birth_label_cells(born, bsel, np.array([0.3, 0.1, 0.4]), 5) == [(5, 2), (6, 1)]
    assert birth_label_cells(born, bsel, np.array([0.3, 0.1, 0.4]), 6) == [(6, 1)]  # 5 not new
