"""Property tests (Hypothesis, deterministic profile) of the filter core's invariants."""

import warnings

from hypothesis import given, strategies as st
import numpy as np
import pytest

from extended_tracker.config import TrackerConfig
from extended_tracker.filter import cardinality as cphd
from extended_tracker.filter.cardinality import (
    predict_cardinality, predict_cardinality_log, resize_cardinality,
)
from extended_tracker.filter.distance import distance_partitions
from extended_tracker.filter.ggiw import cell_stats, predict, update_pairs
from extended_tracker.filter.mixture import IW_OFFSET, Mixture
from extended_tracker.filter.partition import build_partitions
from extended_tracker.filter.reduction import merge_components, reduce_mixture
from extended_tracker.filter.state import FilterState
from extended_tracker.tracker import filter_step, TrackerState

from mixtures import pedestrians

CFG = TrackerConfig()


def is_spd(A):
    A = np.asarray(A)
    sym = np.allclose(A, np.swapaxes(A, -1, -2), rtol=1e-9, atol=1e-12)
    return sym and bool(np.all(np.linalg.eigvalsh(A) > 0))


@st.composite
def mixtures(draw, max_k=5):
    k = draw(st.integers(1, max_k))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    m = np.column_stack([rng.uniform(-5, 5, (k, 2)), rng.normal(0, 1, (k, 2))])
    A = rng.normal(0, 0.5, (k, 4, 4))
    P = A @ np.swapaxes(A, 1, 2) + 1e-3 * np.eye(4)
    v = rng.uniform(6.5, 200, k)
    B = rng.normal(0, 0.4, (k, 2, 2))
    X = B @ np.swapaxes(B, 1, 2) + 1e-3 * np.eye(2)
    V = X * (v - IW_OFFSET)[:, None, None]
    return Mixture(rng.uniform(0.01, 1.0, k), rng.uniform(0.1, 50, k), rng.uniform(0.05, 10, k),
                   m, P, v, V, rng.integers(0, 3, k))


@st.composite
def point_sets(draw, max_n=40):
    n = draw(st.integers(0, max_n))
    seed = draw(st.integers(0, 2**31 - 1))
    rng = np.random.default_rng(seed)
    centres = rng.uniform(-4, 4, (3, 2))
    pts = centres[rng.integers(0, 3, n)] + rng.normal(0, draw(st.sampled_from([0.02, 0.2, 1.0])),
                                                     (n, 2))
    if n > 3 and draw(st.booleans()):
        pts[1] = pts[0]                                # a repeated detection
    return pts


@given(mixtures(), point_sets(), st.floats(0.0, 2.0))
def test_predict_and_update_keep_parameters_valid(mix, pts, dt):
    pred = predict(mix, dt, 0.99, 2.0, 2.0, 2.0)
    assert is_spd(pred.P) and is_spd(pred.V)
    assert np.all(pred.v > IW_OFFSET) and np.all(pred.alpha > 0) and np.all(pred.beta > 0)
    if len(pts) == 0:
        return
    cells = [np.arange(len(pts))]
    if len(pts) > 2:
        cells = [np.arange(len(pts) // 2), np.arange(len(pts) // 2, len(pts))]
    stats = cell_stats(pts, cells)
    comp = np.repeat(np.arange(len(pred)), len(cells))
    cell = np.tile(np.arange(len(cells)), len(pred))
    out = update_pairs(pred, comp, stats, cell, 0.25, 0.03 ** 2 * np.eye(2))
    assert np.all(np.isfinite(out.log_lik))
    assert is_spd(out.P) and is_spd(out.V)
    assert np.all(out.v > IW_OFFSET) and np.all(out.alpha > 0) and np.all(out.beta > 0)


@given(point_sets(), st.floats(0.0, 0.5), st.floats(0.05, 2.0))
def test_every_partition_covers_each_detection_once(pts, d_min, span):
    from dataclasses import replace

    cfg = replace(CFG.partition, d_min=d_min, d_max=d_min + span)
    pset = build_partitions(pts, cfg)
    assert pset.partitions
    for part in pset.partitions:
        members = np.concatenate([pset.cells[c] for c in part]) if len(part) else np.zeros(0)
        assert sorted(members.tolist()) == list(range(len(pts)))
    # cells are distinct
    keys = {tuple(c.tolist()) for c in pset.cells}
    assert len(keys) == len(pset.cells)


@given(point_sets(), st.integers(1, 4), st.integers(1, 6))
def test_the_caps_always_leave_a_partition(pts, max_parts, max_cells):
    """However tight the caps, the first partition is taken: a scan always updates."""
    from dataclasses import replace

    cfg = replace(CFG.partition, max_partitions=max_parts, max_cells=max_cells)
    pset = build_partitions(pts, cfg)
    assert 1 <= len(pset.partitions) <= max_parts
    for part in pset.partitions:
        members = np.concatenate([pset.cells[c] for c in part]) if len(part) else np.zeros(0)
        assert sorted(members.tolist()) == list(range(len(pts)))



@given(point_sets(max_n=40), st.booleans())
def test_no_partition_is_offered_twice(pts, predicted):
    """Duplicates removed: the distance, prediction, sub- and small-cell partitions of a
    scan are distinct as sets of cells (a partition counted twice would count its
    hypothesis twice in the update)."""
    pred = None
    if predicted and len(pts):
        k = len(pts[:2])
        pred = {'centre': pts[:2].copy(), 'gate_inv': np.array([np.eye(2) / 0.09] * k),
                'gate': 13.8, 'rate': np.full(k, 6.0)}
    pset = build_partitions(pts, CFG.partition, pred)
    as_sets = [frozenset(tuple(pset.cells[c].tolist()) for c in part)
               for part in pset.partitions]
    assert len(set(as_sets)) == len(as_sets)


def test_the_cell_cap_counts_every_cell_it_turns_away():
    """Two pairs of returns 0.25 m apart, 5 m from each other, and room for 4 cells: the
    finest partition takes four lone returns; the next (the pairs, two new cells) would
    pass the cap and is turned away, two cells counted."""
    from dataclasses import replace

    cfg = replace(CFG.partition, d_min=0.1, d_max=0.8, max_cells=4, split_small=0,
                  sub_partition=False, prediction_partition=False)
    pts = np.array([[0.0, 0.0], [0.25, 0.0], [5.0, 0.0], [5.25, 0.0]])    # exact in binary
    pset = build_partitions(pts, cfg)
    assert [p.tolist() for p in pset.partitions] == [[0, 1, 2, 3]]
    assert (pset.capped_cells, pset.capped_partitions) == (2, 0)


def test_the_partition_cap_thins_the_thresholds_evenly_from_finest_to_coarsest():
    """Thirty returns on a line, the gaps growing by 2 cm from 0.11 m: 30 distinct
    thresholds in [d_min, d_max]; with room for 5 partitions they are the finest, the
    coarsest (one cell) and three between, not the five finest."""
    from dataclasses import replace

    cfg = replace(CFG.partition, d_min=0.1, d_max=0.8, max_partitions=5, split_small=0,
                  sub_partition=False, prediction_partition=False)
    gaps = 0.11 + 0.02 * np.arange(29)
    pts = np.column_stack([np.concatenate([[0.0], np.cumsum(gaps)]), np.zeros(30)])
    pset = build_partitions(pts, cfg)
    sizes = [len(p) for p in pset.partitions]
    assert len(sizes) == 5 and sizes[0] == 30 and sizes[-1] == 1
    assert pset.capped_partitions == 30 - 5

def assert_same_partition_sets(a, b):
    """Two PartitionSets hold the same cells and partitions, in order, and the same cap
    counters."""
    assert [c.tolist() for c in a.cells] == [c.tolist() for c in b.cells]
    assert [p.tolist() for p in a.partitions] == [p.tolist() for p in b.partitions]
    assert (a.capped_partitions, a.capped_cells) == (b.capped_partitions, b.capped_cells)


@given(point_sets(max_n=60), st.floats(0.0, 0.5), st.floats(0.05, 2.0),
       st.integers(1, 12), st.integers(1, 80), st.booleans())
def test_nested_add_equals_one_add_per_partition(pts, d_min, span, max_parts, max_cells, first):
    """
    ``PartitionSet.add_nested`` (only changed cells looked up) gives the same cells,
    partitions and cap counters as :meth:`PartitionSet.add` on each partition in turn,
    also after another partition was added first (shared cells, a duplicate partition).
    """
    from extended_tracker.filter.partition import PartitionSet

    dist, _ = distance_partitions(pts, d_min, d_min + span, 40)
    sets = PartitionSet(), PartitionSet()
    if first and len(pts):
        for p in sets:
            p.add(dist[len(dist) // 2].copy(), max_parts, max_cells)
    for labels in dist:
        sets[0].add(labels, max_parts, max_cells)
    sets[1].add_nested(dist, max_parts, max_cells)
    assert_same_partition_sets(*sets)


@given(point_sets(max_n=60), st.floats(0.0, 0.5), st.integers(2, 4), st.integers(1, 12),
       st.integers(1, 80), st.booleans())
def test_small_cell_splits_equal_one_add_per_label_array(pts, d_min, split_small, max_parts,
                                                        max_cells, nested_first):
    """
    The small cells' lone-return partitions (the finest partition's cells derived once)
    give the same cells, partitions and cap counters as :meth:`PartitionSet.add` on each
    variant's label array, the cell's returns relabelled past every other label; with
    the distance partitions added first or not at all.
    """
    from extended_tracker.filter.partition import PartitionSet

    dist, _ = distance_partitions(pts, d_min, d_min + 0.5, 40)
    if not len(pts):
        return
    sets = PartitionSet(), PartitionSet()
    if nested_first:
        for p in sets:
            p.add_nested(dist, max_parts, max_cells)
    finest = dist[0]
    m = len(finest)
    counts = np.bincount(finest, minlength=m)
    for lab in ((counts >= 2) & (counts <= split_small)).nonzero()[0].tolist():
        split = finest.copy()
        idx = (finest == lab).nonzero()[0]
        split[idx] = m + idx
        sets[0].add(split, max_parts, max_cells)
    sets[1].add_splits(finest, split_small, max_parts, max_cells)
    assert_same_partition_sets(*sets)


@given(point_sets(max_n=25), st.floats(0.05, 1.5))
def test_distance_partition_matches_definition(pts, d):
    """Threshold partition == connected components of 'closer than d' (checked by BFS)."""
    labels, _ = distance_partitions(pts, d, d, 1)
    if not len(pts):
        return
    lab = labels[0]
    n = len(pts)
    dist = np.linalg.norm(pts[:, None] - pts[None], axis=2)
    seen = -np.ones(n, int)
    comp = 0
    for s in range(n):
        if seen[s] >= 0:
            continue
        stack = [s]
        seen[s] = comp
        while stack:
            i = stack.pop()
            for j in np.flatnonzero((dist[i] <= d) & (seen < 0)):
                seen[j] = comp
                stack.append(j)
        comp += 1
    # same grouping up to renaming
    pairs = {(a, b) for a, b in zip(lab.tolist(), seen.tolist())}
    assert len(pairs) == len(set(lab.tolist())) == len(set(seen.tolist()))


@given(point_sets(max_n=60), st.floats(0.0, 0.5), st.floats(0.05, 2.0), st.integers(1, 40))
def test_distance_labels_by_pass_and_by_jumping_agree(pts, d_min, span, max_thresholds):
    """The two ways of reading the labels off the merges (a Python root pass per threshold
    for few returns, numpy pointer jumping for many) give the same arrays, each label the
    smallest index of its cell."""
    from extended_tracker.filter import distance as partition

    saved = partition.PASS_MAX_RETURNS
    try:
        partition.PASS_MAX_RETURNS = 10 ** 9
        by_pass, dropped_pass = distance_partitions(pts, d_min, d_min + span, max_thresholds)
        partition.PASS_MAX_RETURNS = 0
        by_jumping, dropped = distance_partitions(pts, d_min, d_min + span, max_thresholds)
    finally:
        partition.PASS_MAX_RETURNS = saved
    assert dropped == dropped_pass and len(by_pass) == len(by_jumping)
    for x, y in zip(by_pass, by_jumping):
        assert x.dtype == y.dtype == np.int64
        np.testing.assert_array_equal(x, y)
        first = {}
        for i, lab in enumerate(x.tolist()):
            first.setdefault(lab, i)
        assert all(lab == i for lab, i in first.items())


def test_a_merge_at_exactly_a_threshold_joins_and_each_threshold_comes_once():
    """The thresholds are closed ('closer than or as close as d'), and each distinct one
    gives one partition: returns exactly 0.5 m apart are one cell at 0.5, and with
    d_min = d_max = 0.5 there is that one partition, not two alike."""
    pts = np.array([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0], [3.0, 0.0]])
    parts, dropped = distance_partitions(pts, 0.25, 0.5, 10)
    assert [p.tolist() for p in parts] == [[0, 1, 2, 3], [0, 0, 0, 3]] and dropped == 0
    parts, _ = distance_partitions(pts, 0.5, 0.5, 10)
    assert [p.tolist() for p in parts] == [[0, 0, 0, 3]]


def test_kmeans_ends_at_a_lloyd_fixed_point():
    """Each point is nearest the mean of its own cluster: two tight groups 0.6 m apart,
    5 m out along one ray (centres pulled towards the origin would take the inner points
    of the far group)."""
    from extended_tracker.filter.kmeans import kmeans_pp

    rng = np.random.default_rng(11)
    direction = np.array([0.6, 0.8])
    pts = np.concatenate([5.0 * direction + rng.normal(0, 0.08, (5, 2)),
                          5.6 * direction + rng.normal(0, 0.08, (5, 2))])
    labels = kmeans_pp(pts, 2, seed=3)
    means = np.array([pts[labels == c].mean(axis=0) for c in range(2)])
    nearest = np.linalg.norm(pts[:, None] - means[None], axis=2).argmin(axis=1)
    assert (nearest == labels).all()
    assert sorted(np.bincount(labels).tolist()) == [5, 5]


def test_kmeans_of_identical_points_and_a_centre_that_takes_none():
    """Points that all coincide: no second centre can be drawn (every distance is 0), and
    k-means returns one cluster. A given centre that no point is nearest stays where it
    is (it is not moved to the origin, where it would take the points near the sensor)."""
    from extended_tracker.filter.kmeans import kmeans_pp

    same = np.tile([[2.0, 1.0]], (5, 1))
    assert kmeans_pp(same, 2, seed=0).tolist() == [0] * 5
    pts = np.array([[0.1, 0.0], [0.15, 0.05], [1.0, 0.0], [1.05, 0.05]])
    labels = kmeans_pp(pts, 2, init=np.array([[0.6, 0.0], [50.0, 50.0]]))
    assert labels.tolist() == [0, 0, 0, 0]


def test_sub_partitioning_splits_a_cell_where_the_predictions_stand():
    """Four returns on a 0.25 m square (its sides exact in binary, so all four join at
    one threshold: one cell), under two confident predictions one above the other: the
    cell is split into the pair below and the pair above, k-means started at the
    predicted centres. K-means has other fixed points here: k-means++ from the default
    seed ends at one corner against the other three."""
    from dataclasses import replace

    from extended_tracker.filter.kmeans import kmeans_pp

    pts = np.array([[5.0, 0.0], [5.25, 0.0], [5.0, 0.25], [5.25, 0.25]])
    assert kmeans_pp(pts, 2, seed=0).tolist() == [1, 0, 0, 0]
    predicted = {'centre': np.array([[5.125, 0.0], [5.125, 0.25]]),
                 'gate_inv': np.array([np.eye(2) / 0.04] * 2), 'gate': 9.0,
                 'rate': np.array([2.0, 2.0])}
    cfg = replace(CFG.partition, prediction_partition=False, split_small=0)
    pset = build_partitions(pts, cfg, predicted)
    cells = [sorted(tuple(pset.cells[c].tolist()) for c in part) for part in pset.partitions]
    assert [(0, 1), (2, 3)] in cells and [(0, 2), (1, 3)] not in cells


def test_prediction_partition_takes_only_the_returns_inside_a_gate():
    """Returns inside a confident prediction's gate go to it; one outside every gate keeps
    its distance-partition cell, however near the gate's edge."""
    from extended_tracker.filter.partition import prediction_partition

    predicted = {'centre': np.array([[0.0, 0.0], [2.0, 0.0]]),
                 'gate_inv': np.array([np.eye(2) / 0.01] * 2), 'gate': 9.0}   # 0.3 m
    pts = np.array([[0.2, 0.0], [0.0, 0.29], [0.45, 0.0], [1.85, 0.1], [2.0, 0.5],
                    [0.0, -0.31]])
    fallback = np.array([0, 0, 2, 3, 3, 5])
    labels = prediction_partition(pts, predicted, fallback)
    assert labels.tolist() == [0, 0, 2 + 2, 1, 2 + 3, 2 + 5]



def test_the_confident_predictions_are_labels_heaviest_parts_of_weight_half_or_more():
    """
    What steers prediction and sub-partitioning: each label's heaviest component when
    it weighs at least 0.5, with its centre, its expected returns and the inverse of its
    predicted measurement spread (position covariance, expected extent and sensor noise,
    written out here). A label whose heaviest part is lighter steers nothing, though its
    parts add up to more (label 4: 0.3 + 0.3); with none there is none.
    """
    from extended_tracker.filter.update import gate_threshold, gates, sensor_noise

    P = np.diag([0.04, 0.09, 0.3, 0.3])
    V = 6.0 * np.diag([0.09, 0.04])                    # v 12: E[X] = V / (v - 6)
    mix = Mixture(np.array([0.7, 0.3, 0.4, 0.2, 0.3, 0.3]),
                  np.array([12.0, 20.0, 30.0, 8.0, 9.0, 9.0]), np.ones(6),
                  np.array([[2.0, 0.0, 0, 0], [2.5, 0.5, 0, 0], [5.0, 1.0, 0, 0],
                            [8.0, 0.0, 0, 0], [9.0, 0.0, 0, 0], [9.0, 0.2, 0, 0]]),
                  np.tile(P, (6, 1, 1)), np.full(6, 12.0), np.tile(V, (6, 1, 1)),
                  np.array([1, 1, 2, 3, 4, 4]))
    _, confident = gates(mix, CFG)
    assert confident['centre'].tolist() == [[2.0, 0.0]]       # label 1's 0.7
    assert confident['rate'].tolist() == [12.0]
    R = sensor_noise(CFG)
    np.testing.assert_allclose(confident['gate_inv'][0],
                               np.linalg.inv(P[:2, :2] + V / 6.0 + R), rtol=1e-12)
    assert confident['gate'] == gate_threshold(CFG)
    light = Mixture(mix.w[2:], mix.alpha[2:], mix.beta[2:], mix.m[2:], mix.P[2:], mix.v[2:],
                    mix.V[2:], mix.label[2:])
    assert gates(light, CFG)[1] is None

def test_a_cell_of_four_returns_across_two_predictions_is_also_offered_split():
    """Sub-partitioning splits a cell of at least four returns that confident predictions
    say holds several objects: four returns 0.08 m apart (closer than d_min, so one cell
    in every distance partition) with a confident prediction on each half; some partition
    has the halves as two cells, which no distance partition has (prediction
    partitioning, which would offer the same, is off)."""
    from dataclasses import replace

    cfg = replace(TrackerConfig().partition, prediction_partition=False)

    def cell_sets(pset):
        return [sorted(sorted(pset.cells[c].tolist()) for c in part)
                for part in pset.partitions]

    pts = np.array([[3.0, -0.12], [3.0, -0.04], [3.0, 0.04], [3.0, 0.12]])
    predicted = {'centre': np.array([[3.0, -0.08], [3.0, 0.08]]),
                 'gate_inv': np.array([np.eye(2) / 0.09] * 2), 'gate': 13.8,
                 'rate': np.array([2.0, 2.0])}
    assert [[0, 1], [2, 3]] in cell_sets(build_partitions(pts, cfg, predicted))
    assert [[0, 1], [2, 3]] not in cell_sets(build_partitions(pts, cfg))



def test_a_long_cell_is_split_into_as_many_objects_as_its_size_says():
    """
    Sub-partitioning splits a cell into the larger of the number of confident predictions
    that gate it and the count its size suggests at their mean rate (the Poisson mode of
    k with 18 returns at k x 6 a scan: 3). Eighteen returns 5 cm apart (one cell at every
    threshold) gated by two predictions of 6 returns each: some partition holds them as
    three cells; at 18 returns a scan each, two.
    """
    from dataclasses import replace

    cfg = replace(CFG.partition, prediction_partition=False, split_small=0)
    pts = np.column_stack([3.0 + 0.05 * np.arange(18), np.zeros(18)])

    def most_cells(rate):
        predicted = {'centre': np.array([[3.2, 0.0], [3.65, 0.0]]),
                     'gate_inv': np.array([np.eye(2) / 0.25] * 2), 'gate': 13.8,
                     'rate': np.array([rate, rate])}
        pset = build_partitions(pts, cfg, predicted)
        return max(len(p) for p in pset.partitions)

    assert most_cells(6.0) == 3 and most_cells(18.0) == 2

@given(mixtures(max_k=6))
def test_merging_preserves_weight_and_validity(mix):
    idx = np.arange(len(mix))
    W, a, b, m, P, v, V, lab = merge_components(mix, idx)
    assert np.isclose(W, mix.w.sum(), rtol=1e-12)
    assert a > 0 and b > 0 and v > IW_OFFSET
    assert is_spd(P) and is_spd(V)
    # the merged Gamma keeps the mixture's mean rate
    assert np.isclose(a / b, np.sum(mix.w * mix.alpha / mix.beta) / W, rtol=1e-9)
    reduced, _ = reduce_mixture(mix, 0.0, 1e9, 1000)
    assert np.isclose(reduced.w.sum(), mix.w.sum(), rtol=1e-12)


@given(st.lists(st.floats(0.0, 1.0), min_size=3, max_size=41), st.floats(0.5, 1.0),
       st.floats(0.0, 3.0))
def test_cardinality_prediction_is_a_pmf(raw, p_s, birth):
    p = np.asarray(raw) + 1e-9
    p = p / p.sum()
    out = np.exp(predict_cardinality(np.log(p), p_s, birth))
    assert np.isclose(out.sum(), 1.0, atol=1e-12)
    assert np.all(out >= 0)


@given(st.lists(st.floats(0.0, 1.0), min_size=3, max_size=41), st.floats(0.5, 1.0),
       st.floats(0.0, 3.0))
def test_cardinality_prediction_matches_enumeration(raw, p_s, birth):
    """
    Oracle: each of l objects survives independently with p_S (binomial thinning), then
    a Poisson number is born; enumerate every l and every number of survivors with
    scipy's binomial and Poisson pmfs, drop what lies beyond N_max and renormalise.
    """
    p = np.asarray(raw) + 1e-9
    p = p / p.sum()
    want = _enumerated_prediction(p, p_s, birth)
    with np.errstate(divide='ignore'):                    # p_s = 1: log(1 - p_s)
        for form in (predict_cardinality, predict_cardinality_log):
            got = np.exp(form(np.log(p), p_s, birth))
            np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-15)


def _enumerated_prediction(p, p_s, birth):
    """The predicted pmf by enumeration with scipy's binomial and Poisson pmfs."""
    from scipy.stats import binom, poisson

    n_max = len(p) - 1
    want = np.zeros(n_max + 1)
    for n_prev, p_prev in enumerate(p):
        for s in range(n_prev + 1):
            born = np.arange(n_max + 1 - s)
            want[s + born] += p_prev * binom.pmf(s, n_prev, p_s) * poisson.pmf(born, birth)
    return want / want.sum()


@pytest.mark.parametrize('p_s, n_max, product', [
    (0.9, 40, True), (1e-3, 40, True), (1.0 - 1e-9, 20, True), (1.0 - 1e-9, 40, False),
    (1e-12, 40, False), (0.9, 41, False)])
def test_cardinality_thinning_forms_against_enumeration(monkeypatch, p_s, n_max, product):
    """
    The thinning runs as exact binomials times powers of p_S / q_S and q_S where those
    stay within the double range (N_max times the larger log below 600) and from the
    weights' logs elsewhere: a survival of 1 - 1e-9 over N_max 20 (20 log(1e9) = 414)
    takes products, over 40 (829) the logs, and so do 1e-12 over 40 and an N_max past
    THIN_PRODUCT_MAX (set to 40 here, for a short enumeration). Both against the
    enumeration (scipy's pmfs), the form taken checked by its table.
    """
    monkeypatch.setattr(cphd, 'THIN_PRODUCT_MAX', 40)
    rng = np.random.default_rng(n_max)
    p = rng.random(n_max + 1) + 1e-3
    p /= p.sum()
    tables = []
    binomials = cphd.binomial_table
    monkeypatch.setattr(cphd, 'binomial_table', lambda n: tables.append(n) or binomials(n))
    got = np.exp(predict_cardinality(np.log(p), p_s, 0.7))
    assert bool(tables) == product
    # tolerance: enumeration and the two forms round differently, each term within
    # some N_max units in the last place
    np.testing.assert_allclose(got, _enumerated_prediction(p, p_s, 0.7), rtol=1e-9,
                               atol=1e-15)


def test_cardinality_prediction_limits(monkeypatch):
    """No death and no birth leave the pmf as it is; certain death leaves none. N_max = 40
    objects for sure, all surviving, and a birth mean of 1e10: the birth pmf's entries up
    to N_max reach 1e10^40 / 40!, past what the running product holds, so the log-domain
    form stands in (without a warning) and keeps the 40."""
    import extended_tracker.filter.cardinality as cphd

    p = np.array([0.1, 0.2, 0.3, 0.4])
    with np.errstate(divide='ignore'):
        np.testing.assert_allclose(np.exp(predict_cardinality(np.log(p), 1.0, 0.0)), p,
                                   rtol=1e-14)
        np.testing.assert_allclose(np.exp(predict_cardinality(np.log(p), 0.0, 0.0)),
                                   [1.0, 0.0, 0.0, 0.0], atol=1e-300)
        calls = []
        monkeypatch.setattr(cphd, 'predict_cardinality_log',
                            lambda *a: calls.append(a) or predict_cardinality_log(*a))
        forty = np.log(np.eye(41)[40])
        with warnings.catch_warnings():
            warnings.simplefilter('error')
            got = np.exp(predict_cardinality(forty, 1.0, 1e10))
    assert len(calls) == 1
    np.testing.assert_array_equal(got, np.eye(41)[40])


@given(st.lists(st.floats(0.0, 1.0), min_size=1, max_size=41), st.integers(0, 60))
def test_cardinality_resized_to_a_new_n_max(raw, n_max):
    """Oracle: the pmf conditioned on n <= n_max (zeros beyond the old length); a pmf with
    no mass there is put at n_max."""
    p = np.asarray(raw)
    with np.errstate(divide='ignore'):
        got = np.exp(resize_cardinality(np.log(p / p.sum()) if p.sum() else np.log(p), n_max))
    want = np.zeros(n_max + 1)
    k = min(len(p), n_max + 1)
    want[:k] = p[:k]
    if want.sum() > 0:
        want /= want.sum()
    else:
        want[n_max] = 1.0
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-300)


def test_filter_follows_n_max_changed_while_running():
    from extended_tracker.config import from_dict
    from extended_tracker.filter.state import predict_state

    rng = np.random.default_rng(3)
    state = TrackerState.initial(CFG)
    for _ in range(3):
        state, _, _ = filter_step(state, rng.normal(0, 1.0, (20, 2)), 0.1, CFG)
    for n_max in (12, 60):
        cfg = from_dict({'model': {'n_max': n_max}})
        pred = predict_state(state.filter, 0.1, cfg)
        assert len(pred.log_card) == n_max + 1
        new, est, _ = filter_step(state, rng.normal(0, 1.0, (20, 2)), 0.1, cfg)
        assert len(new.filter.log_card) == n_max + 1
        assert np.isclose(np.exp(new.filter.log_card).sum(), 1.0, atol=1e-9)


def test_birth_regions_enter_the_prediction_and_its_cardinality():
    """Each configured region (x, y, std) is a birth component at rest at (x, y) with
    position std ``std``, the birth prior's velocity, extent and rate, weight
    ``birth.weight`` and a label of its own; its weight adds to the predicted cardinality's
    mean (from no objects: the regions' weights plus the uniform birth ``rate dt``). A
    walker standing in a region is then reported under the region's label."""
    from extended_tracker.config import from_dict
    from extended_tracker.filter.state import predict_state

    cfg = from_dict({'birth': {'regions': [1.0, 2.0, 0.3, 4.0, -1.0, 0.6], 'weight': 0.2}})
    b = cfg.birth
    state = FilterState.initial(cfg)
    pred = predict_state(state, 0.1, cfg)
    mix = pred.mixture
    np.testing.assert_array_equal(mix.m, [[1.0, 2.0, 0.0, 0.0], [4.0, -1.0, 0.0, 0.0]])
    np.testing.assert_allclose(mix.P[:, [0, 1, 2, 3], [0, 1, 2, 3]],
                               [[0.09, 0.09, b.velocity_std ** 2, b.velocity_std ** 2],
                                [0.36, 0.36, b.velocity_std ** 2, b.velocity_std ** 2]])
    assert not np.any(mix.P[:, [0, 0, 1], [1, 2, 3]])
    np.testing.assert_array_equal(mix.w, [0.2, 0.2])
    np.testing.assert_array_equal(mix.label, [state.next_label, state.next_label + 1])
    assert pred.next_label == state.next_label + 2
    np.testing.assert_allclose(mix.expected_extent(), [b.extent_semi_axis ** 2 * np.eye(2)] * 2)
    np.testing.assert_allclose(mix.alpha / mix.beta, b.expected_rate)
    card = np.exp(pred.log_card)
    assert np.isclose(card @ np.arange(len(card)), 0.4 + b.rate * 0.1, rtol=1e-9)

    # a walker at the first region: its returns, the same every scan (an arc of radius
    # 0.2 m facing the scanner at the origin)
    t = np.linspace(-1.2, 1.2, 12) + np.arctan2(-2.0, -1.0)
    walker = np.column_stack([1.0 + 0.2 * np.cos(t), 2.0 + 0.2 * np.sin(t)])
    state = TrackerState.initial(cfg)
    first = state.filter.next_label
    for _ in range(8):
        state, est, _ = filter_step(state, walker, 0.1, cfg)
    assert list(est.label) == [first]
    assert np.linalg.norm(est.m[0, :2] - [1.0, 2.0]) < 0.2


@pytest.mark.slow
@given(st.integers(0, 10_000), st.sampled_from(['cphd', 'phd']))
def test_filter_step_cardinality_sums_to_one(seed, mode):
    from extended_tracker.config import from_dict

    cfg = from_dict({'model': {'mode': mode, 'surveillance_area': 400.0}})
    rng = np.random.default_rng(seed)
    state = TrackerState.initial(cfg)
    for _ in range(4):
        pts = rng.normal(0, 1.0, (rng.integers(0, 30), 2))
        state, est, diag = filter_step(state, pts, 0.1, cfg)
        mix = state.filter.mixture
        card = np.exp(state.filter.log_card)
        assert np.isclose(card.sum(), 1.0, atol=1e-9)
        assert len(est) <= len(np.unique(mix.label))
        assert is_spd(mix.P) if len(mix) else True


def _sparse_merges(pts, d_max, delaunay):
    """The spanning-forest path of ``distance.single_linkage_merges`` (scipy's sparse MST),
    forced: over the Delaunay edges, or over the radius graph's pairs as where qhull
    fails."""
    import extended_tracker.filter.distance as P

    saved = P.LINKAGE_MAX, P.delaunay_pairs
    try:
        P.LINKAGE_MAX = -1
        if not delaunay:
            P.delaunay_pairs = lambda points: None
        return P.single_linkage_merges(pts, d_max)
    finally:
        P.LINKAGE_MAX, P.delaunay_pairs = saved


@pytest.mark.parametrize('shape', ['blob', 'line'])
def test_a_dense_blob_past_the_linkage_size_is_not_listed_pair_by_pair(monkeypatch, shape):
    """100 returns past the linkage size, all within a few dozen cm: the radius graph's
    780 000 pairs (every pair) are never listed (a 12 700-return scan took 0.7 s and 1 GB
    to list its 12 million); the Delaunay edges are taken. On a line, where there is no
    triangulation, the pairs are listed. The spanning forest's edge lengths are single
    linkage's over all pairs either way."""
    from scipy.cluster.hierarchy import linkage
    from scipy.spatial.distance import pdist

    import extended_tracker.filter.distance as P

    rng = np.random.default_rng(3)
    n = P.LINKAGE_MAX + 100
    pts = (rng.normal(0.0, 0.1, (n, 2)) if shape == 'blob'
           else np.column_stack([np.sort(rng.uniform(0, 3, n)), np.zeros(n)]))
    listed = []

    class Tree(P.cKDTree):
        def query_pairs(self, *args, **kwargs):
            listed.append(1)
            return super().query_pairs(*args, **kwargs)

    monkeypatch.setattr(P, 'cKDTree', Tree)
    _, _, height = P.single_linkage_merges(pts, 0.8)
    assert len(listed) == (shape == 'line')
    z = linkage(pdist(pts), method='single')
    assert np.allclose(np.sort(height), z[z[:, 2] <= 0.8, 2], rtol=0, atol=1e-12)


@given(point_sets(max_n=90), st.floats(0.05, 1.5), st.booleans())
def test_linkage_and_sparse_spanning_forests_agree(pts, d_max, delaunay):
    """
    Single linkage over all pairs and scipy's sparse MST over the radius graph's pairs, or
    over its Delaunay edges (the path past the linkage size): same forest weight and size, and each
    merge joins two clusters under their smallest index, given first.
    """
    import extended_tracker.filter.distance as P

    for a, b, h in (P.single_linkage_merges(pts, d_max), _sparse_merges(pts, d_max, delaunay)):
        assert np.all(np.diff(h) >= 0) and np.all(h <= d_max)
        assert len(a) == len(b) == len(h)
        parent = list(range(len(pts)))
        for u, v in zip(a, b):
            assert parent[u] == u and parent[v] == v and u < v      # both are roots
            parent[v] = u
    dense, sparse = P.single_linkage_merges(pts, d_max), _sparse_merges(pts, d_max, delaunay)
    assert len(dense[2]) == len(sparse[2])
    # MST weights are unique even when edges tie; rounding of 1e-12 lifts allowed
    assert np.isclose(dense[2].sum(), sparse[2].sum(), rtol=1e-12, atol=1e-9)


@given(st.integers(0, 10_000), st.integers(3, 300), st.integers(0, 5))
def test_delaunay_edges_are_the_triangulations_edges_each_once(seed, n, repeats):
    """The edges taken from the triangulation equal its simplices' sides, sorted within
    each edge and deduplicated row by row (numpy's unique over rows, the plain reading),
    with each repeated point joined to the vertex it coincides with."""
    from scipy.spatial import Delaunay

    from extended_tracker.filter.distance import delaunay_pairs

    rng = np.random.default_rng(seed)
    pts = rng.normal(0.0, 1.0, (n, 2))
    pts = np.vstack([pts, pts[rng.integers(0, n, repeats)]])
    tri = Delaunay(pts)
    s = tri.simplices
    e = np.concatenate([s[:, [0, 1]], s[:, [1, 2]], s[:, [0, 2]], tri.coplanar[:, [0, 2]]])
    expected = np.unique(np.sort(e, axis=1), axis=0)
    got = delaunay_pairs(pts)
    assert len(tri.coplanar) == repeats          # each repeat is left out, and joined
    assert np.array_equal(got, expected)


def test_dense_blob_path_on_degenerate_inputs():
    """Collinear returns (qhull cannot triangulate) and repeated ones on the Delaunay path."""
    import extended_tracker.filter.distance as P

    line = np.column_stack([np.linspace(0, 3, 80), np.zeros(80)])
    blob = np.vstack([np.random.default_rng(1).normal(0, 0.05, (120, 2)), [[5.0, 5.0]] * 3])
    for pts in (line, blob):
        dense = P.single_linkage_merges(pts, 0.5)
        got = _sparse_merges(pts, 0.5, True)
        assert len(got[2]) == len(dense[2])
        assert np.isclose(got[2].sum(), dense[2].sum(), rtol=1e-12, atol=1e-9)


def likeliest_object_count(n_points: int, rate: float, k_max: int) -> int:
    """The reference: the k in 1..k_max under which n_points is likeliest for a Poisson
    count of mean k * rate, by scipy, one cell at a time."""
    from scipy.stats import poisson

    k = np.arange(1, k_max + 1)
    return int(k[np.argmax(poisson.logpmf(n_points, k * rate))])


@given(st.lists(st.integers(1, 200), min_size=1, max_size=10), st.floats(0.5, 40.0))
def test_vectorised_object_count_matches_scalar(ns, rate):
    from extended_tracker.filter.partition import expected_object_counts

    got = expected_object_counts(np.array(ns), np.full(len(ns), rate), 4)
    assert got.tolist() == [likeliest_object_count(n, rate, 4) for n in ns]


@given(st.lists(mixtures(max_k=4), min_size=1, max_size=4))
def test_batched_merge_equals_per_group_reference(groups_of):
    """merge_groups (one vectorised Newton solve) == merge_gamma / merge_iw per group."""
    from extended_tracker.filter.reduction import merge_gamma, merge_groups, merge_iw

    mix = Mixture.concat(groups_of)
    sizes = np.cumsum([0] + [len(g) for g in groups_of])
    groups = [np.arange(a, b) for a, b in zip(sizes[:-1], sizes[1:])]
    out = merge_groups(mix, groups)
    for k, idx in enumerate(groups):
        a, b = merge_gamma(mix.w[idx], mix.alpha[idx], mix.beta[idx])
        v, V = merge_iw(mix.w[idx], mix.v[idx], mix.V[idx])
        # both solve the same scalar equations by Newton to ~1e-10 relative
        assert np.isclose(out.alpha[k], a, rtol=1e-9) and np.isclose(out.beta[k], b, rtol=1e-9)
        assert np.isclose(out.v[k], v, rtol=1e-9)
        np.testing.assert_allclose(out.V[k], V, rtol=1e-7, atol=1e-12)
        assert np.isclose(out.w[k], mix.w[idx].sum(), rtol=1e-12)


def test_non_finite_detections_are_refused_with_a_clear_error():
    """The scan conversion masks bad beams; a direct caller of the core is told plainly."""
    import pytest

    state = TrackerState.initial(CFG)
    pts = np.array([[1.0, 2.0], [np.nan, 1.0], [1.05, np.inf]])
    with pytest.raises(ValueError, match='2 of 3 rows'):
        filter_step(state, pts, 0.1, CFG)


def test_seeded_generator_restarts_like_a_new_one():
    """
    k-means draws from a cached generator put back to its seeded state: every call must
    give what ``default_rng(seed)`` gives, whatever was drawn before, in any thread.
    """
    import threading

    from extended_tracker.filter.kmeans import seeded_generator

    def draws(seed):
        return seeded_generator(seed).random(5)

    for seed in (0, 7, 0):
        expected = np.random.default_rng(seed).random(5)
        assert np.array_equal(draws(seed), expected)
        seeded_generator(seed + 1).random(3)          # another stream in between
        assert np.array_equal(draws(seed), expected)
    out = {}
    thread = threading.Thread(target=lambda: out.update(d=draws(0)))
    thread.start()
    thread.join()
    assert np.array_equal(out['d'], np.random.default_rng(0).random(5))


def test_extraction_reports_the_map_count_of_heaviest_labels_each_by_its_heaviest_part():
    """CPHD: the MAP count of labels, heaviest first, none lighter than min_existence
    (0.3); each reported at its heaviest component, with its label's weight."""
    from dataclasses import replace as evolve

    from extended_tracker.tracks.extract import extract

    cfg = TrackerConfig()
    mix = pedestrians([(1, 0.6, 0.0, 0.0), (1, 0.3, 0.1, 0.0), (2, 0.3, 5.0, 0.0),
                       (2, 0.5, 5.2, 0.0), (3, 0.25, 9.0, 0.0)])
    log_card = np.full(cfg.model.n_max + 1, -np.inf)
    log_card[3] = 0.0                                   # the MAP count: all three labels
    est = extract(evolve(FilterState.initial(cfg), mixture=mix, log_card=log_card), cfg)
    assert est.label.tolist() == [1, 2]                 # label 3 (0.25) is too light
    np.testing.assert_allclose(est.m[:, :2], [[0.0, 0.0], [5.2, 0.0]])
    np.testing.assert_allclose(est.existence, [0.9, 0.8])
    log_card[3], log_card[1] = -np.inf, 0.0             # the MAP count: one
    est = extract(evolve(FilterState.initial(cfg), mixture=mix, log_card=log_card), cfg)
    assert est.label.tolist() == [1]
    # the most probable count, not the rounded mean: p(1) 0.4, p(3) 0.35, p(4) 0.25 (mean
    # 2.45) reports one label
    log_card = np.full(cfg.model.n_max + 1, -np.inf)
    log_card[[1, 3, 4]] = np.log([0.4, 0.35, 0.25])
    est = extract(evolve(FilterState.initial(cfg), mixture=mix, log_card=log_card), cfg)
    assert est.label.tolist() == [1]


def test_components_larger_than_any_object_or_lost_within_metres_are_dropped():
    """reduction.max_semi_axis (4 m) and max_position_std (3 m): a little over either is
    implausible, a little under is kept; lost along one axis is lost (the last two: std
    3.3 m across x only, then along y only)."""
    from extended_tracker.filter.update import implausible

    cfg = TrackerConfig()
    k = 6
    semi = np.array([3.6, 4.4, 0.3, 0.3, 0.3, 0.3])
    std_x = np.array([0.1, 0.1, 2.7, 3.3, 3.3, 0.1])
    std_y = np.array([0.1, 0.1, 2.7, 3.3, 0.1, 3.3])
    P = np.zeros((k, 4, 4))
    P[:, 0, 0], P[:, 1, 1] = std_x ** 2, std_y ** 2
    P[:, 2, 2] = P[:, 3, 3] = 0.1
    V = (20.0 - IW_OFFSET) * semi[:, None, None] ** 2 * np.eye(2)
    mix = Mixture(np.ones(k), np.full(k, 10.0), np.ones(k), np.zeros((k, 4)), P,
                  np.full(k, 20.0), V, np.arange(k))
    assert implausible(mix, cfg).tolist() == [False, True, False, True, True, True]


@pytest.mark.parametrize('open_std, kept', [(6.0, [True, True, False, False]),
                                             (2.0, [False, False, False, False])])
def test_labels_with_nothing_static_in_front_coast_on_to_the_open_limit(open_std, kept):
    """
    Position stds 2.9, 4.5, 6.5 m, and 4.5 m of a label not named: past
    ``max_position_std`` (3 m) a component of a label ``in_open`` is kept up to
    ``max_open_position_std`` (6 m), the others are dropped; an open limit of 2 m drops
    even the first.
    """
    from extended_tracker.config import from_dict
    from extended_tracker.filter.update import implausible

    cfg = from_dict({'reduction': {'max_open_position_std': open_std}})
    std = np.array([2.9, 4.5, 6.5, 4.5])
    P = np.tile(np.eye(4) * 0.1, (4, 1, 1))
    P[:, 0, 0] = P[:, 1, 1] = std ** 2
    V = (20.0 - IW_OFFSET) * 0.09 * np.eye(2)
    mix = Mixture(np.ones(4), np.full(4, 10.0), np.ones(4), np.zeros((4, 4)), P,
                  np.full(4, 20.0), np.tile(V, (4, 1, 1)), np.array([1, 1, 2, 3]))
    assert (~implausible(mix, cfg, np.array([1, 2]))).tolist() == kept
    three_metres_for_all = [True, False, False, False]
    assert (~implausible(mix, cfg)).tolist() == three_metres_for_all
    assert (~implausible(mix, cfg, np.array([], dtype=int))).tolist() == three_metres_for_all


@pytest.mark.parametrize('scale', [0.3, 1.5, 3.0, 4.5])
def test_implausible_extents_against_eigvalsh(scale):
    """The extent test against numpy's eigenvalues, whether every trace is under the limit
    (no eigenvalue taken) or not: a semi-axis over max_semi_axis is implausible, whatever
    the ellipse's shape and orientation."""
    from extended_tracker.filter.update import implausible

    cfg = TrackerConfig()
    rng = np.random.default_rng(int(scale * 10))
    k = 200
    semi = rng.uniform(0.05, 1.0, (k, 2)) * scale
    yaw = rng.uniform(0, np.pi, k)
    R = np.stack([np.stack([np.cos(yaw), -np.sin(yaw)], -1),
                  np.stack([np.sin(yaw), np.cos(yaw)], -1)], -2)
    X = R @ (semi[:, :, None] ** 2 * np.eye(2)) @ R.swapaxes(1, 2)
    v = np.full(k, 20.0)
    P = np.tile(np.eye(4) * 0.01, (k, 1, 1))
    mix = Mixture(np.ones(k), np.full(k, 10.0), np.ones(k), np.zeros((k, 4)), P, v,
                  X * (v - IW_OFFSET)[:, None, None], np.arange(k))
    major2 = np.linalg.eigvalsh(mix.expected_extent())[:, -1]
    expected = major2 > cfg.reduction.max_semi_axis ** 2
    assert implausible(mix, cfg).tolist() == expected.tolist()
    if scale < 2:
        assert not expected.any()
    if scale > 4:
        assert expected.any() and not expected.all()



def test_birth_labels_one_per_set_of_cells_sharing_returns_or_the_claiming_label():
    """
    Birth cells that share a return (a cell and its sub-cells) are one new object, one
    label; cells with none in common are others, labelled in order from ``next_label``.
    A birth cell on which an existing label has more detected weight than the birth
    takes that label (an object restarted); with less, it is new.
    """
    from extended_tracker.filter.births import label_births
    from extended_tracker.filter.partition import PartitionSet

    pset = PartitionSet(cells=[np.array([0, 1]), np.array([1, 2]), np.array([5]),
                               np.array([2, 3]), np.array([7])])
    labels, nxt = label_births(pset, np.array([0, 1, 2, 3]), 10)
    assert labels.tolist() == [10, 10, 11, 10] and nxt == 12     # 0-1-3 chained by 1, 2
    claim = np.array([0, 0, 4, 0, 6])
    claim_w = np.array([0.0, 0.0, 0.3, 0.0, 0.2])
    birth_w = np.array([0.5, 0.5, 0.2, 0.5, 0.3])
    labels, nxt = label_births(pset, np.array([2, 4]), 10, claim, claim_w, birth_w)
    assert labels.tolist() == [4, 10] and nxt == 11


def test_a_labels_detections_are_its_heaviest_cells_where_detection_outweighs_a_miss():
    """A label's detected cell: the cell of its heaviest detected pair, when its detected
    weight exceeds its missed weight; none otherwise."""
    from extended_tracker.filter.assemble import detected_cells

    mix = Mixture(np.ones(3), np.full(3, 10.0), np.ones(3), np.zeros((3, 4)),
                  np.tile(np.eye(4), (3, 1, 1)), np.full(3, 20.0),
                  np.tile(np.eye(2), (3, 1, 1)), np.array([1, 1, 2]))
    comp, cell = np.array([0, 1, 2, 2]), np.array([0, 1, 2, 1])
    w_det = np.array([0.2, 0.5, 0.1, 0.05])          # label 1: 0.7 detected, 2: 0.15
    w_missed = np.array([0.1, 0.1, 0.6])               # label 1: 0.2 missed, 2: 0.6
    assert detected_cells(mix, comp, cell, w_det, w_missed) == {1: 1}
    w_missed[2] = 0.1
    assert detected_cells(mix, comp, cell, w_det, w_missed) == {1: 1, 2: 2}


@pytest.mark.parametrize('n', [2, 3, 7, 40])
def test_a_cells_width_is_the_segment_its_returns_lie_evenly_along(n):
    """``n`` returns evenly spaced along a segment 0.37 m long, at any heading: the width
    is the segment's length; a lone return has none."""
    from extended_tracker.filter.assemble import cell_widths

    pieces = [np.linspace(0.0, 0.37, n)[:, None] * [np.cos(h), np.sin(h)] + [1.0, 2.0]
              for h in np.radians([0.0, 30.0, 90.0, 200.0])]
    pts = np.vstack(pieces + [[[5.0, 5.0]]])
    cells = [np.arange(k * n, (k + 1) * n) for k in range(4)] + [np.array([4 * n])]
    widths = cell_widths(cell_stats(pts, cells))
    np.testing.assert_allclose(widths, [0.37] * 4 + [0.0], atol=1e-12)


def test_far_parts_of_a_label_become_new_objects_when_heavy_and_go_when_light():
    """
    ``split_labels`` (merge distance 4 in the metric of the head's position covariance
    plus extent, here 0.0425 m^2: 0.41 m; split weight 0.4): a part within the distance
    stays; far parts of weight 0.4 or more get fresh labels, heaviest first, from
    ``next_label``; a far light part is dropped; other labels are untouched.
    """
    from extended_tracker.tracks.labels import split_labels

    rows = [(1, 0.9, 0.0, 0.0), (1, 0.3, 0.3, 0.0), (1, 0.5, 1.0, 0.0), (1, 0.7, 0.0, 1.5),
            (1, 0.45, 0.45, 0.0), (1, 0.05, -1.0, 0.0), (2, 0.8, 5.0, 0.0)]
    out, nxt = split_labels(pedestrians(rows), 0.4, 4.0, 10)
    assert nxt == 13
    got = {(round(x, 2), round(y, 2)): int(lab)
           for (x, y), lab in zip(out.m[:, :2].tolist(), out.label)}
    assert got == {(0.0, 0.0): 1, (0.3, 0.0): 1, (0.0, 1.5): 10, (1.0, 0.0): 11,
                   (0.45, 0.0): 12, (5.0, 0.0): 2}
    lone = pedestrians([(1, 0.9, 0.0, 0.0), (2, 0.8, 5.0, 0.0)])
    assert split_labels(lone, 0.4, 4.0, 10) == (lone, 10)


def test_a_reported_labels_existence_is_its_weight_clipped_to_one():
    from dataclasses import replace as evolve

    from extended_tracker.tracks.extract import extract

    cfg = TrackerConfig()
    mix = pedestrians([(1, 0.8, 0.0, 0.0), (1, 0.5, 0.1, 0.0), (2, 0.6, 5.0, 0.0)])
    log_card = np.full(cfg.model.n_max + 1, -np.inf)
    log_card[2] = 0.0
    est = extract(evolve(FilterState.initial(cfg), mixture=mix, log_card=log_card), cfg)
    assert est.label.tolist() == [1, 2] and est.existence.tolist() == [1.0, 0.6]
    # the expected rate of the part reported: alpha / beta
    est = extract(evolve(FilterState.initial(cfg), mixture=evolve(mix, beta=np.full(3, 4.0)),
                         log_card=log_card), cfg)
    assert est.rate.tolist() == [2.5, 2.5]
