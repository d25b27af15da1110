"""The thin pieces of one contour (a car seen across a corner) reported as one object."""

from __future__ import annotations

import numpy as np

from ..filter.distance import find_root, union_min
from .estimates import Estimates
from .identity import _norm

# a thin contour piece (see group_segments): semi-minor axis at most this, semi-major at least.
# A car's end piece often holds a stretch of its side by the corner as well, which
# takes its semi-minor axis to 0.16-0.24 m (mixed_traffic)
SEGMENT_MAX_SEMI_MINOR = 0.25        # m


SEGMENT_MIN_SEMI_MAJOR = 0.5         # m


# a piece moving faster than people walk is a vehicle's, and counts from this length on: a
# nearer object's shadow or a gap in sparse returns cuts a bicycle's side or a car's end
# into pieces of 0.4-0.5 m, while a person's track (a leg pair at leg height, seen as an
# arc) reaches 0.4-0.5 m too, standing or walking (MiR's circling walkers)
SEGMENT_FAST_MIN_SEMI_MAJOR = 0.4    # m


SEGMENT_FAST_SPEED = 2.5             # m/s


# a piece seen growing from one end (a car's side as it drives into view, or out from
# behind something) moves its centre at about half the car's speed: the velocities of
# pieces of one object may differ by this much of the faster one's speed, on top of
# ``speed``. In mixed_traffic the side of the car driving in moved at 2.0-2.7 m/s while
# the car and its end moved at 5 m/s
GROWING_LAG = 0.5


def group_segments(est: Estimates, seniority: np.ndarray, gap: float, speed: float):
    """
    Report the thin pieces of one object's contour as that object.

    A laser sees a car across a corner as an L: its long side and its end. Two thin
    ellipses explain those returns far better than one ellipse over the car does (the
    model spreads detections over the extent, the scanner sees the contour), so the filter
    tracks two thin objects. Pieces at most ``SEGMENT_MAX_SEMI_MINOR`` thick and at least
    ``SEGMENT_MIN_SEMI_MAJOR`` long, one of which has an end within ``gap`` of the other
    piece (of its segment, not only of its ends), and whose velocities differ by at most
    ``speed`` plus ``GROWING_LAG`` times the faster one's speed are reported as one
    object (a piece moving at ``SEGMENT_FAST_SPEED`` or more counts from
    ``SEGMENT_FAST_MIN_SEMI_MAJOR``): the rectangle around them in the frame of the
    longest piece (its extent the rectangle's second moments), moving at their
    rate-weighted velocity, under the label of the longest piece (between pieces of one
    length, the most ``seniority``, reported scans in a row, then the smaller label), its
    position covariance that piece's. Existence and visibility are the pieces' largest,
    rate and detections their sums.

    The longest piece, not the most senior, because ungrouped it is the piece nearest the
    object: when the grouping comes and goes from scan to scan, the report stays on one
    label. The most senior piece as the head raised ``mixed_traffic``'s id switches from
    4/3/3/3 to 6/3/11/5 (the results table's four variants, when this was written).

    Returns the estimates (ascending labels) and the number of pieces grouped into
    another's report.

    Notes
    -----
    The side's estimate reaches past the car's ends or short of them: its centre lags a
    moving car and its length is a second moment. In ``mixed_traffic`` the end piece's
    end touched the side 1 m in from the side's estimated end, and with the ends alone
    compared the car was two reports there.
    """
    k = len(est)
    if gap <= 0 or k < 2:
        return est, 0
    pieces = _thin_pieces(est)
    if pieces is None:
        return est, 0
    seg, major, minor, u, half, ends = pieces
    roots = _touching(est, seg, u, half, ends, gap, speed)
    if roots is None:
        return est, 0
    keep = np.ones(k, dtype=bool)
    out = Estimates(est.label.copy(), est.existence.copy(), est.m.copy(), est.P.copy(),
                    est.X.copy(), est.rate.copy(), est.num_detections.copy(),
                    est.visibility.copy())
    grouped = 0
    for r in np.unique(roots):
        members = (roots == r).nonzero()[0]
        if len(members) < 2:
            continue
        rows = seg[members]
        # the longest piece carries the report (ungrouped, it is the one nearest the
        # object), then the most senior: most scans in a row, then the oldest
        head = rows[np.lexsort((est.label[rows], -seniority[rows], -major[members]))[0]]
        _report_group(out, est, head, rows, members, major, minor, u, ends)
        keep[rows] = False
        keep[head] = True
        grouped += len(rows) - 1
    return out.take(keep), grouped


def _thin_pieces(est: Estimates):
    """
    ``(seg, major, minor, u, half, ends)`` of the thin pieces among the estimates: their
    rows, semi-axes, unit vectors along them, their rectangles' half-lengths and end
    points ((2s, 2): the first ends, then the second); None if fewer than two.
    """
    # the semi-major axis squared is at most the trace: people are ruled out at once
    X = est.X
    long_ = (X[:, 0, 0] + X[:, 1, 1] >= SEGMENT_FAST_MIN_SEMI_MAJOR ** 2).nonzero()[0]
    if len(long_) < 2:
        return None
    major, minor, yaw = (a[long_] for a in est.axes())
    fast = _norm(est.m[long_, 2:], 1) >= SEGMENT_FAST_SPEED
    thin = (minor <= SEGMENT_MAX_SEMI_MINOR) & (
        (major >= SEGMENT_MIN_SEMI_MAJOR) | (fast & (major >= SEGMENT_FAST_MIN_SEMI_MAJOR)))
    seg, major, minor, yaw = long_[thin], major[thin], minor[thin], yaw[thin]
    if len(seg) < 2:
        return None
    u = np.stack([np.cos(yaw), np.sin(yaw)], axis=1)
    half = (0.5 * np.sqrt(3.0)) * major                # half the rectangle's length
    centre = est.m[seg, :2]
    ends = np.concatenate([centre + half[:, None] * u, centre - half[:, None] * u])
    return seg, major, minor, u, half, ends


def _touching(est: Estimates, seg, u, half, ends, gap: float, speed: float):
    """
    The group (root piece) of each piece: pieces touch when an end of one comes within
    ``gap`` of the other piece (the nearest point of its segment, the nearer of the two
    ways round) and their velocities differ by at most ``speed`` plus ``GROWING_LAG``
    times the faster one's speed. None if none touch.
    """
    s = len(seg)
    centre = est.m[seg, :2]
    rel = ends[:, None, :] - centre[None, :, :]                          # (2s, s, 2)
    t = np.clip(np.sum(rel * u[None], axis=2), -half[None], half[None])
    off = rel - t[:, :, None] * u[None]
    d = _norm(off, 2).reshape(2, s, s).min(axis=0)
    d = np.minimum(d, d.T)
    v = est.m[seg, 2:]
    dv = _norm(v[:, None] - v[None], 2)
    pace = _norm(v, 1)
    near = (d <= gap) & (dv <= speed + GROWING_LAG * np.maximum.outer(pace, pace))
    np.fill_diagonal(near, False)
    if not near.any():
        return None
    parent = list(range(s))
    for i, j in zip(*near.nonzero()):
        union_min(parent, int(i), int(j))
    return np.array([find_root(parent, i) for i in range(s)])


def _report_group(out: Estimates, est: Estimates, head: int, rows, members, major, minor,
                  u, ends) -> None:
    """Write the report of one group of pieces into row ``head`` of ``out``: the rectangle
    around them in the frame of the longest piece, their rate-weighted velocity, the
    largest existence and visibility, the summed rate and detections."""
    s = len(major)
    ux, uy = u[members[np.argmax(major[members])]]
    frame = np.array([[ux, -uy], [uy, ux]])            # the longest piece's axis, its normal
    pts = np.concatenate([ends[members], ends[s + members]]) @ frame
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    length = hi[0] - lo[0]
    width = hi[1] - lo[1] + np.sqrt(3.0) * minor[members].max()
    w = np.maximum(est.rate[rows], 1e-9)
    out.m[head, :2] = frame @ (0.5 * (lo + hi))
    out.m[head, 2:] = (w[:, None] * est.m[rows, 2:]).sum(axis=0) / w.sum()
    out.X[head] = frame @ np.diag([length ** 2 / 3.0, width ** 2 / 3.0]) @ frame.T
    out.existence[head] = est.existence[rows].max()
    out.visibility[head] = est.visibility[rows].max()
    out.rate[head] = est.rate[rows].sum()
    out.num_detections[head] = est.num_detections[rows].sum()
