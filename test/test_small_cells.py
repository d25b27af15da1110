"""
Returns closer together than ``partition.d_min`` share a cell in every distance partition;
``partition.split_small`` also tries such a cell of up to that many returns as lone
returns, so that the update can weigh an object there against clutter (which comes one
return at a time). The partitions it adds, and the birth weight of a tight pair against
the closed form of the ET-PHD's two partitions at several clutter rates.
"""

import numpy as np
import pytest

from extended_tracker.config import from_dict
from extended_tracker.filter.partition import build_partitions
from extended_tracker.tracker import filter_step, TrackerState

# a walker's returns (a dozen, 4 cm apart), a tight pair and a tight triple, far apart
BLOB = np.column_stack([np.full(12, 4.0), np.linspace(-0.22, 0.22, 12)])
PAIR = np.array([[2.0, 3.0], [2.0, 3.03]])
TRIPLE = np.array([[2.0, -3.0], [2.02, -3.0], [2.04, -3.0]])


def partitions_of(points, split_small):
    """Each partition of ``points`` as a set of frozensets of detection indices."""
    cfg = from_dict({'partition': {'split_small': split_small}}).partition
    pset = build_partitions(points, cfg)
    return [{frozenset(pset.cells[c].tolist()) for c in p} for p in pset.partitions]


@pytest.mark.parametrize('split_small, alone', [(0, []), (1, []), (2, ['pair']),
                                                (3, ['pair', 'triple'])])
def test_small_cells_are_also_tried_as_lone_returns(split_small, alone):
    """Each cell of 2 up to ``split_small`` returns of the finest distance partition gets
    one partition more, that one with its returns alone; the cells themselves stay in the
    others, and nothing else is split."""
    pts = np.vstack([BLOB, PAIR, TRIPLE])
    pair = frozenset([12, 13])
    triple = frozenset([14, 15, 16])
    blob = frozenset(range(12))
    parts = partitions_of(pts, split_small)
    base = partitions_of(pts, 0)
    for p in parts:
        assert sorted(i for c in p for i in c) == list(range(len(pts)))
    # the pair and the triple are one cell in every distance partition
    assert all(pair in p and triple in p for p in base)
    for name, cell in (('pair', pair), ('triple', triple)):
        lone = [p for p in parts if cell not in p]
        if name in alone:
            assert len(lone) == 1
            assert all(frozenset([i]) in lone[0] for i in cell)
            # the rest of that partition is the finest distance partition's
            assert lone[0] - {frozenset([i]) for i in cell} == base[0] - {cell}
        else:
            assert not lone
    assert all(blob in p for p in parts)
    assert len(parts) == len(base) + len(alone)


def birth_weight(points, clutter_rate, split_small, area=100.0):
    """Weight of the new object after one PHD update of an empty state with ``points``."""
    cfg = from_dict({'model': {'mode': 'phd', 'clutter_rate': clutter_rate},
                     'partition': {'split_small': split_small}})
    state, _, _ = filter_step(TrackerState.initial(cfg), points, 0.1, cfg, clutter_area=area)
    return float(state.filter.mixture.w.sum())


def test_a_tight_pair_is_weighed_against_two_clutter_returns():
    """
    A pair 3 cm apart, alone in the scan, no track. With its returns also alone, the
    ET-PHD has two partitions: {W}, with d_W = psi_W / (lambda^2 c1 c2), and {z1}, {z2},
    with d = 1 each (no object explains a lone return: births need two). The new
    object's weight is omega_{W} = d_W / (1 + d_W), so with ``a = psi_W / (c1 c2)``
    (independent of the clutter rate lambda) it is ``a / (a + lambda^2)``: one rate fixes
    ``a`` and the closed form must give the others. Without the split the pair is an
    object whatever the clutter rate.
    """
    rates = [0.5, 1.0, 2.0, 5.0, 8.0]
    w = np.array([birth_weight(PAIR, lam, 2) for lam in rates])
    assert np.all((w > 0.02) & (w < 0.999))
    assert np.all(np.diff(w) < 0)                   # more clutter, less of an object
    a = rates[0] ** 2 * w[0] / (1.0 - w[0])
    np.testing.assert_allclose(w, a / (a + np.square(rates)), rtol=1e-9)
    unsplit = [birth_weight(PAIR, lam, 0) for lam in rates]
    np.testing.assert_allclose(unsplit, 1.0, rtol=1e-9)


def test_a_walker_is_born_as_before():
    """A dozen returns spread over 0.44 m hold no cell of two or three: the split adds
    no partition and the walker's birth is the same."""
    assert partitions_of(BLOB, 2) == partitions_of(BLOB, 0)
    assert birth_weight(BLOB, 1.0, 2) == birth_weight(BLOB, 1.0, 0)
