"""
Results that do not rest on the last bit: the same on every CPU.

numpy computes float64 ``exp``, ``log``, ``arctan2`` and the like with kernels it picks by
CPU, and they differ in the last bit. The tracker's thresholds and orderings must not turn
such bits into other ids (``lastbit.other_cpu`` stands in for another CPU).
"""

import itertools
from pathlib import Path

import numpy as np
import pytest

from extended_tracker.bag.replay import replay_results
from extended_tracker.cli import load_config, REAL_TOPICS
from extended_tracker.filter.mixture import Mixture

from lastbit import assert_same_tracks, other_cpu

pytestmark = pytest.mark.slow  # whole scenes at several scan rates, or replays

REAL = Path(__file__).resolve().parents[2] / 'shared' / 'data' / 'real'
MIR = 'mir_legs_test_stationary'


def test_weights_equal_but_for_rounding_order_by_index():
    """
    The CPHD update gives every cell that one component alone explains its partition's
    weight, each through roundings of its own: two such components of one label tie, and
    the first of them heads the label whichever carries the larger last bit.
    """
    w = 0.904776
    for pair in ([w, np.nextafter(w, 1.0)], [np.nextafter(w, 1.0), w]):
        mix = Mixture(np.array([0.1] + pair), np.ones(3), np.ones(3), np.zeros((3, 4)),
                      np.broadcast_to(np.eye(4), (3, 4, 4)), np.full(3, 10.0),
                      np.broadcast_to(np.eye(2), (3, 2, 2)), np.array([7, 7, 7]))
        order, is_head, _ = mix.by_label()
        assert order.tolist() == [1, 2, 0] and is_head.tolist() == [True, False, False]
    # weights that differ beyond rounding still order by weight
    mix = Mixture(np.array([0.5, 0.9]), np.ones(2), np.ones(2), np.zeros((2, 4)),
                  np.broadcast_to(np.eye(4), (2, 4, 4)), np.full(2, 10.0),
                  np.broadcast_to(np.eye(2), (2, 2, 2)), np.array([7, 7]))
    assert mix.by_label()[0].tolist() == [1, 0]


def _replay(name, scans):
    cfg = load_config(None)
    return [(res.estimates.label.tolist(), res.estimates.m.copy()) for _, res in
            itertools.islice(replay_results(REAL / name, cfg, REAL_TOPICS.get(name)), scans)]


@pytest.mark.skipif(not (REAL / MIR).is_dir(), reason='no ../shared/data/real beside the clone')
def test_a_real_replay_is_the_same_on_another_cpu(monkeypatch):
    """
    The MiR recording, replayed as another CPU would compute it, gives the same ids and
    tracks. (Until the furniture there was learned as background, scan 427 held a label
    with two components of exactly that kind of tie, 8 cm apart; broken by the last bit,
    the label's report moved 0.8 m and an id changed at scan 435. The replay no longer
    meets that tie; the test above pins it.)
    """
    plain = _replay(MIR, 737)
    other_cpu(monkeypatch)
    assert_same_tracks(plain, _replay(MIR, 737), 1e-6, least=700)
