"""Small hand-made GGIW mixtures, estimates and report records for the label tests, and a
comparison of two filter states (imported by the tests, not a test)."""

import numpy as np

from extended_tracker.filter.mixture import IW_OFFSET, Mixture
from extended_tracker.tracks.estimates import Estimates


def pedestrians(rows):
    """rows: (label, weight, x, y); standing, pedestrian-sized (0.2 m), 5 cm position std."""
    k = len(rows)
    lab, w, x, y = (np.array(c) for c in zip(*rows))
    m = np.column_stack([x, y, np.zeros(k), np.zeros(k)]).astype(float)
    P = np.broadcast_to(np.diag([0.05 ** 2, 0.05 ** 2, 0.1, 0.1]), (k, 4, 4)).copy()
    v = np.full(k, 20.0)
    V = np.broadcast_to((20.0 - IW_OFFSET) * 0.2 ** 2 * np.eye(2), (k, 2, 2)).copy()
    return Mixture(w.astype(float), np.full(k, 10.0), np.ones(k), m, P, v, V,
                   lab.astype(np.int64))


def estimates(labels, xy):
    """Standing point estimates: ``labels`` at positions ``xy``, everything else neutral."""
    k = len(labels)
    m = np.zeros((k, 4))
    m[:, :2] = xy
    return Estimates(np.array(labels, dtype=np.int64), np.ones(k), m, np.zeros((k, 4, 4)),
                     np.zeros((k, 2, 2)), np.ones(k), np.zeros(k, np.int64), np.ones(k))


FIELDS = ('w', 'alpha', 'beta', 'm', 'P', 'v', 'V', 'label')


def assert_same_posterior(got, want):
    """Two filter states' mixtures agree field by field (to 1e-12 relative, 1e-14
    absolute) and their cardinalities to 1e-12: the same update, to rounding. Tracker
    states are compared by their filter states."""
    got, want = getattr(got, 'filter', got), getattr(want, 'filter', want)
    for f in FIELDS:
        np.testing.assert_allclose(getattr(got.mixture, f), getattr(want.mixture, f),
                                   rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(got.log_card, want.log_card, rtol=1e-12, atol=1e-12)


def reported(record, labels, scans, origin, size=0.25):
    """The track ``record`` with ``labels`` reported in the last ``scans`` scans in a row, returns
    updating each of them every time, first at ``origin`` (k, 2) with semi-major axis
    ``size``, and nothing travelled: their report record as ``record_reports`` keeps it."""
    from dataclasses import replace as evolve

    labels, scans = np.asarray(labels, np.int64), np.asarray(scans, np.int64)
    k = len(labels)
    return evolve(record, reported=labels, reported_scans=scans, reported_hits=scans.copy(),
                  reported_origin=np.array(origin, dtype=float).reshape(k, 2),
                  reported_size=np.full(k, size), reported_travel=np.zeros(k))


FILTER_FIELDS = ('mixture', 'log_card', 'next_label')


def with_fields(state, **changes):
    """A ``TrackerState`` with fields of its filter state (``mixture``, ``log_card``,
    ``next_label``) and of its track record replaced, each where it belongs."""
    from dataclasses import replace

    from extended_tracker.tracker import TrackerState

    filt = {k: v for k, v in changes.items() if k in FILTER_FIELDS}
    record = {k: v for k, v in changes.items() if k not in FILTER_FIELDS}
    return TrackerState(replace(state.filter, **filt), replace(state.tracks, **record))
