"""Extraction: the labels reported in a scan, each by its heaviest component."""

from __future__ import annotations

import numpy as np

from ..config import TrackerConfig
from ..filter.mixture import weight_key
from ..filter.state import FilterState
from .estimates import Estimates


def extract(state: FilterState, cfg: TrackerConfig, n_det=None, visibility=None) -> Estimates:
    """
    Report the heaviest labels: ``MAP(p'(n))`` of them in CPHD mode, those heavier than
    ``extraction.phd_threshold`` in PHD mode; never one lighter than ``min_existence``.

    Each label is reported by its heaviest component.
    """
    mix = state.mixture
    if not len(mix):
        return Estimates.empty()
    by_lab, is_head, _ = mix.by_label()
    heads = by_lab[is_head]                            # one per label, labels ascending
    labels, _, weight = mix.per_label()
    ex = cfg.extraction
    # the labels heaviest first (weight_key; ties by label), a handful: a Python sort
    keys = (-weight_key(weight)).tolist()
    order = sorted(range(len(keys)), key=keys.__getitem__)
    w = weight.tolist()
    if cfg.model.mode == 'cphd':
        chosen = order[:int(state.log_card.argmax())]
    else:
        chosen = [i for i in order if w[i] > ex.phd_threshold]
    # in label order (the labels ascend)
    chosen = sorted(i for i in chosen if w[i] >= ex.min_existence)
    if not chosen:
        return Estimates.empty()
    at = np.array(chosen, dtype=np.int64)
    best, lab_w, chosen = heads[at], weight[at], labels[at]
    n_det = n_det or {}
    visibility = visibility or {}
    reported = chosen.tolist()
    return Estimates(
        label=chosen,
        existence=np.minimum(np.maximum(lab_w, 0.0), 1.0),
        m=mix.m[best],
        P=mix.P[best],
        X=mix.expected_extent(best),
        rate=mix.expected_rate()[best],
        num_detections=np.array([n_det.get(x, 0) for x in reported], dtype=np.int64),
        visibility=np.array([visibility.get(x, 1.0) for x in reported]),
    )
