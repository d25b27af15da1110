"""
Objects in one scan: small groups of returns that stand out from what is round them.

The static background and the static map learn what stays still; this tells them what not
to learn.

- A *segment* is a run of returns in beam order, each within ``gap`` of the next
  (``gap``: ``margin``, or ``GAP_BEAMS`` beam spacings at that range if wider). It runs
  across up to ``MAX_SKIPPED`` beams that returned nothing (dropouts), and across lone
  returns (segments of fewer than ``min_points``: a clutter return in front of a person
  does not cut them in two, nor hides their end unless within ``GROUP_GAP`` of it).
- A *group* is the segments no larger than ``object_size`` whose bounding boxes lie
  within ``GROUP_GAP`` of each other, chained: a walker's two legs, a chair's legs, a
  bench's row of legs. A larger segment is a group of its own.
- A group is an *object* when its returns' bounding box has a diagonal of at most
  ``object_size`` (a person, two legs, a chair, a bin, a pole, a child, a dog; not a
  wall, a car, a counter or a bench's row of legs), it has at least ``min_points``
  returns, and each end of each of its segments stands out: the beam beyond it returns
  nothing, or a range farther by over ``margin``, or a return of the group itself (one
  leg in front of the other), or there is no beam (the edge of the field of view is
  open). A piece of wall seen beside a person, or between two, has a nearer return at
  its cut end, and a car's side seen beyond its corner one about as far: no object. Lone
  returns still close an end (a wall seen at a grazing angle returns points apart one by
  one) unless farther than ``GROUP_GAP`` from it (clutter).

A person standing still from start-up is an object, and so is a chair; telling them apart
is the class guess's work (:mod:`tracks.kinds`), not the background's.
"""

from __future__ import annotations

import numpy as np

from ..filter.distance import find_root, union_min
from .scan import ScanPoints

GAP_BEAMS = 3.0            # the gap between a segment's returns: this many beam spacings
MAX_SKIPPED = 2            # most invalid beams (dropouts) a segment runs across
GROUP_GAP = 0.5            # m between the boxes of the segments of one group


def object_beams(sp: ScanPoints, object_size: float, margin: float,
                 min_points: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """
    ``(objects, small)``: which beams (B,) bool return a point of an object (see the
    module's notes), and which one of a group no larger than ``object_size`` with at
    least one end that stands out, whatever hides the others (a walker partly behind
    another; not a piece of wall between a person and a corner). None of them where
    ``object_size`` is 0.
    """
    objects, small = np.zeros(len(sp.angles), dtype=bool), np.zeros(len(sp.angles), dtype=bool)
    if object_size <= 0 or len(sp.beam) < min_points:
        return objects, small
    ranges, lone = _without_lone_returns(sp, margin, min_points)
    valid = np.isfinite(ranges[sp.beam])
    p, beam = sp.points[valid], sp.beam[valid]
    if len(beam) < min_points:
        return objects, small
    seg, starts, count = _segments(p, beam, ranges, sp.angle_step, margin)
    group, fits = _grouped(p, starts, count, object_size, min_points)
    shut, ajar = _end_states(sp, lone, beam, seg, starts, count, group, margin)
    small[beam] = (fits & ajar)[group[seg]]
    objects[beam] = (fits & ~shut)[group[seg]]
    return objects, small


def _without_lone_returns(sp: ScanPoints, margin: float, min_points: int):
    """``(ranges, lone)``: the scan's ranges with the returns of segments of fewer than
    ``min_points`` taken out (inf), and which beams those were."""
    lone = np.zeros(len(sp.ranges), dtype=bool)
    if min_points <= 1:
        return sp.ranges, lone
    seg, _, count = _segments(sp.points, sp.beam, sp.ranges, sp.angle_step, margin)
    lone[sp.beam[(count < min_points)[seg]]] = True
    return np.where(lone, np.inf, sp.ranges), lone


def _grouped(p, starts, count, object_size: float, min_points: int):
    """``(group, fits)``: each segment's group (:func:`_groups`), and per group whether it
    is at most ``object_size`` across (its returns' bounding box) with ``min_points``."""
    lo, hi = np.minimum.reduceat(p, starts, axis=0), np.maximum.reduceat(p, starts, axis=0)
    group = _groups(lo, hi, np.hypot(*(hi - lo).T) <= object_size)
    n = group.max() + 1
    g_lo, g_hi = np.full((n, 2), np.inf), np.full((n, 2), -np.inf)
    np.minimum.at(g_lo, group, lo)
    np.maximum.at(g_hi, group, hi)
    fits = ((np.bincount(group, count, n) >= min_points)
            & (np.hypot(*(g_hi - g_lo).T) <= object_size))
    return group, fits


def _end_states(sp: ScanPoints, lone, beam, seg, starts, count, group, margin):
    """``(shut, ajar)`` per group: whether some end of its segments is hidden, and whether
    some end stands out (:func:`_open`)."""
    beam_group = np.full(len(sp.ranges), -1)
    beam_group[beam] = group[seg]
    ends = np.concatenate([beam[starts], beam[starts + count - 1]])
    sides = np.repeat([-1, 1], len(starts))
    at = np.full((len(sp.ranges), 2), np.nan)
    at[sp.beam] = sp.points
    hidden = ~_open(sp.ranges, at, lone, beam_group, ends, sides, margin)
    end_group = np.concatenate([group, group])
    n = group.max() + 1
    shut, ajar = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
    shut[end_group[hidden]] = True
    ajar[end_group[~hidden]] = True
    return shut, ajar


def _segments(p, beam, ranges, angle_step, margin):
    """Each return's segment, each segment's first return and its count of returns."""
    r = ranges[beam]
    skipped = np.diff(beam)
    gap = np.maximum(margin, GAP_BEAMS * abs(angle_step) * skipped * np.maximum(r[:-1], r[1:]))
    cut = (np.linalg.norm(np.diff(p, axis=0), axis=1) > gap) | (skipped > 1 + MAX_SKIPPED)
    seg = np.concatenate([[0], np.cumsum(cut)])
    starts = np.concatenate([[0], cut.nonzero()[0] + 1])
    return seg, starts, np.diff(np.concatenate([starts, [len(beam)]]))


def _groups(lo: np.ndarray, hi: np.ndarray, small: np.ndarray) -> np.ndarray:
    """A group label (0, 1, ...) per segment: ``small`` segments whose boxes (lo, hi) lie
    within GROUP_GAP of each other, chained; a larger one (a wall, whose box may hold a
    whole room's worth of others) is a group of its own."""
    gap = np.maximum(0.0, np.maximum(lo[:, None] - hi[None], lo[None] - hi[:, None]))
    near = (np.hypot(gap[..., 0], gap[..., 1]) <= GROUP_GAP) & small[:, None] & small[None]
    parent = list(range(len(lo)))
    for i, j in zip(*np.triu(near, 1).nonzero()):
        union_min(parent, int(i), int(j))
    roots = [find_root(parent, i) for i in range(len(lo))]
    return np.unique(roots, return_inverse=True)[1]


def _open(ranges, at, lone, beam_group, ends, sides, margin) -> np.ndarray:
    """
    Whether each segment end beam ``ends`` stands out on its side ``sides`` (-1: the beam
    before it, +1: the one after): no such beam, no return on it, a return farther than
    the end's range by over ``margin`` (what is behind), one of the end's own group, or a
    lone return farther than GROUP_GAP from the end's (clutter; ``at``: each beam's point).
    A return nearer, or about as far (the rest of a surface seen at a grazing angle, a
    car's side beyond its corner), may hide more of it.
    """
    nb = ends + sides
    inside = (nb >= 0) & (nb < len(ranges))
    nb = np.clip(nb, 0, len(ranges) - 1)
    behind = ranges[nb] > ranges[ends] + margin                  # inf: no return
    own = beam_group[nb] == beam_group[ends]
    apart = lone[nb] & (np.linalg.norm(at[nb] - at[ends], axis=1) > GROUP_GAP)
    return ~inside | behind | own | apart
