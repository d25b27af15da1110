"""
Whether the scanner sees legs: the scan's own shape tells a scanner at leg height from one
at body height, so that one default serves both.

At leg height a walker is two narrow clusters side by side (two legs, 0.1-0.4 m apart),
and so are the legs of a chair or a table. At body height a person is one cluster as wide
as a torso. Distance partitioning must then offer a walker's two legs as one cell (its
smallest threshold over the gap between them), while at body height that threshold would
join two people walking close together.

:func:`legs_seen` keeps, per scanner, the share of its scans that showed a leg pair
(:func:`leg_pairs`), averaged over :data:`MEMORY` seconds of its own scans: a second
scanner that does not see the walker does not dilute the first one's pairs. At body
height a pair shows now and then (the two edges of a person half hidden), in a few scans
in a hundred; at leg height, in most scans with a walker in view. Once a share reaches
:data:`SHARE` the legs are seen, and :func:`scan_config` raises the smallest threshold to
``partition.leg_gap`` for the rest of the run: a scanner does not change height. A reset
forgets it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math

import numpy as np

from ..config import TrackerConfig
from .scan import ScanPoints

CLUSTER_GAP = 0.1      # returns farther apart than this (m), or beams apart, are two clusters
LEG_WIDTH = 0.25       # a leg-sized cluster spans at most this much end to end (m)
LEG_POINTS = 2         # and has at least this many returns
LEG_DEPTH = 0.2        # and stands this far in front of what the beams beside it return (m)
PAIR_DISTANCE = (0.1, 0.5)  # the centres of two legs side by side are this far apart (m)
MEMORY = 1.0           # the share of scans showing a leg pair is averaged over this long (s)
SHARE = 0.25           # the legs are seen once that share reaches this


@dataclass(frozen=True)
class LegEvidence:
    """Per scanner (its frame; None: the one scanner), the share of its recent scans that
    showed a leg pair; and whether the legs are seen."""

    shares: tuple[tuple[str | None, float], ...] = ()
    seen: bool = False

    def share(self, scanner: str | None = None) -> float:
        """The share of ``scanner``'s recent scans that showed a leg pair."""
        return dict(self.shares).get(scanner, 0.0)


def leg_pairs(sp: ScanPoints) -> int:
    """
    The number of leg pairs in one scan: two leg-sized clusters next to each other among
    the leg-sized ones in beam order (the wall behind may show between them), their
    centres :data:`PAIR_DISTANCE` apart, with nothing nearer between them (a nearer thing
    between two narrow pieces makes them the edges of one object it hides in part). The
    points come in beam order, as :func:`scan.scan_to_points` gives them.
    """
    p, beam = sp.points, sp.beam
    if len(p) < 2 * LEG_POINTS:
        return 0
    starts, ends = _clusters(p, beam)
    r = sp.ranges[beam]
    near, far = np.minimum.reduceat(r, starts), np.maximum.reduceat(r, starts)
    centre = np.add.reduceat(p, starts) / (ends - starts)[:, None]
    leg = _leg_sized(p, beam, starts, ends, far, sp.ranges).nonzero()[0]
    lo, hi = PAIR_DISTANCE
    pairs = 0
    for a, b in zip(leg[:-1], leg[1:]):
        apart = np.hypot(*(centre[b] - centre[a]))
        behind = near[a + 1:b].min(initial=np.inf) > max(far[a], far[b])
        pairs += bool(lo < apart <= hi and behind)
    return pairs


def _clusters(p: np.ndarray, beam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each cluster of the returns ``p`` (in beam order) starts and ends: a run on
    beams at most two apart (a lone dropout does not break a leg) whose neighbours are at
    most :data:`CLUSTER_GAP` apart."""
    breaks = ((np.hypot(*np.diff(p, axis=0).T) > CLUSTER_GAP) | (np.diff(beam) > 2)).nonzero()[0]
    return np.r_[0, breaks + 1], np.r_[breaks + 1, len(p)]


def _leg_sized(p, beam, starts, ends, far, ranges) -> np.ndarray:
    """
    Which clusters could be a leg: at least :data:`LEG_POINTS` returns spanning at most
    :data:`LEG_WIDTH`, standing :data:`LEG_DEPTH` in front of what the beams beside them
    return (or into nothing). A piece of a wall or a car's side seen at a grazing angle,
    far away, breaks into narrow clusters too, but each lies beside the next.
    """
    beside = np.r_[np.inf, ranges, np.inf]              # the beams before and after
    stands_out = np.minimum(beside[beam[starts]], beside[beam[ends - 1] + 2]) > far + LEG_DEPTH
    return ((ends - starts >= LEG_POINTS) & (np.hypot(*(p[ends - 1] - p[starts]).T) <= LEG_WIDTH)
            & stands_out)


def legs_seen(evidence: LegEvidence, sp: ScanPoints, dt: float, cfg: TrackerConfig,
              scanner: str | None = None) -> LegEvidence:
    """The evidence with this scan of ``scanner``, taken ``dt`` seconds after that
    scanner's last one (nothing more is looked at once the legs are seen, or with
    ``partition.leg_gap`` 0)."""
    if evidence.seen or cfg.partition.leg_gap <= 0:
        return evidence
    keep = math.exp(-max(dt, 0.0) / MEMORY)
    shares = dict(evidence.shares)
    share = keep * shares.get(scanner, 0.0) + (1.0 - keep) * (leg_pairs(sp) > 0)
    shares[scanner] = share
    return LegEvidence(tuple(shares.items()), share >= SHARE)


def scan_config(cfg: TrackerConfig, evidence: LegEvidence) -> TrackerConfig:
    """``cfg`` for a scan: once the legs are seen, the smallest distance threshold is at
    least ``partition.leg_gap``."""
    pc = cfg.partition
    if not evidence.seen or pc.leg_gap <= pc.d_min:
        return cfg
    return replace(cfg, partition=replace(pc, d_min=pc.leg_gap))
