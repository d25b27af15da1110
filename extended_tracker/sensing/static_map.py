"""
Static structure learned online in the fixed frame, for a scanner that moves.

Notes
-----
A per-beam background (:mod:`sensing.background`) is meaningless once the scanner moves:
every beam's range changes as the robot drives. The static map is a square grid of
``map_cell`` cells in the fixed frame, centred on the scanner (``map_radius`` each way;
it scrolls with the scanner and forgets what falls off its edge). Each cell keeps a
score in seconds, the time it was seen occupied less the time it was seen free, within
plus and minus twice ``confirm_time``:

- a cell holding a return gains the scan period;
- a cell a beam crossed short of its return (by more than ``FREE_SHORT_CELLS`` cells,
  and with no return in its 3 x 3 neighbourhood: a grazing beam and the odometry's
  drift keep it off the surface) loses it.

A cell is *observed* once a beam crossed it, or it lay inside what a beam hit (from a
cell and a half to ``BEHIND`` beyond the return: an object that stood from start-up and
then drives away from the scanner moves its near side into it). A surface only ever
returned (a far wall, hit by a beam now and then) stays unobserved. A return
is *background* (dropped) when a cell of its 3 x 3 neighbourhood (which absorbs the
drift of odometry and the spacing of the beams)

- has a score of at least ``confirm_time / 4``: something has stood there a few scans,
  at least as long as the place was seen empty; or
- was never observed before this scan (hidden, out of range, first seen after a turn),
  and the return is not protected: nothing is known to have moved into it, and a wall
  that comes into view is far more likely than a person. A person who walks out of such
  a place steps into seen space within a few scans.

So what moves into space seen empty is foreground at once, the test of moving objects
used by trackers on driving vehicles. Returns near protecting tracks (confirmed,
person-sized, moved: the caller decides, as for the per-beam background) never raise a
score: a person who walks and stops is never learned. One who stands still before any
track protects them is learned after about ``confirm_time`` where the place was unknown,
more where it was seen empty; one who stands still from start-up is learned, as by the
per-beam background. Odometry that drifts by more than a cell between two visits of a
place leaves the old cells to be cleared by the beams that cross them and the new ones
to be learned, a scan period at a time.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from ..frames.pose import Pose2
from .scan import ScanPoints

FREE_SHORT_CELLS = 3        # a beam clears cells only this many cells short of its return
OCCUPIED = 0.25             # of confirm_time: the score from which a cell is static
BEHIND = 0.5                # m beyond a return that count as the inside of what it hit


@dataclass(frozen=True)
class StaticMap:
    """
    The grid, (n, n) arrays: ``score`` (s) and ``observed`` (crossed by a beam, or inside
    what one hit); and the fixed-frame index of its cell ``[0, 0]``.
    """

    corner: tuple[int, int]
    cell: float
    score: np.ndarray
    observed: np.ndarray

    @staticmethod
    def around(pose: Pose2, cfg) -> 'StaticMap':
        n = 2 * int(math.ceil(cfg.map_radius / cfg.map_cell)) + 1
        centre = _cell_of(np.array([[pose.x, pose.y]]), cfg.map_cell)[0]
        return StaticMap((int(centre[0]) - n // 2, int(centre[1]) - n // 2), cfg.map_cell,
                         np.zeros((n, n), np.float32), np.zeros((n, n), bool))

    @staticmethod
    def seeded(pose: Pose2, sp: ScanPoints, background: np.ndarray, cfg) -> 'StaticMap':
        """
        A map around a scanner that starts to move, from what its per-beam background
        knew of this scan's returns (``background``, a mask over ``sp.points``): those
        cells static, the cells of the others seen (so they are judged by their score,
        not as unknown space). The beams' crossings are added by the first update.
        """
        smap = StaticMap.around(pose, cfg)
        ij, inside = smap.index(pose.to_outer(sp.points))
        smap.observed[ij[inside, 0], ij[inside, 1]] = True
        static = inside & background
        smap.score[ij[static, 0], ij[static, 1]] = 2.0 * cfg.confirm_time
        return smap

    def recentred(self, pose: Pose2, cfg) -> 'StaticMap':
        """The map scrolled (by whole cells) to keep the scanner within its middle half;
        the cells that leave are forgotten."""
        n = len(self.score)
        centre = _cell_of(np.array([[pose.x, pose.y]]), self.cell)[0]
        ci, cj = int(centre[0]) - self.corner[0], int(centre[1]) - self.corner[1]
        if abs(ci - n // 2) <= n // 4 and abs(cj - n // 2) <= n // 4:
            return self
        fresh = StaticMap.around(pose, cfg)
        di, dj = fresh.corner[0] - self.corner[0], fresh.corner[1] - self.corner[1]
        src = (slice(max(di, 0), n + min(di, 0)), slice(max(dj, 0), n + min(dj, 0)))
        dst = (slice(max(-di, 0), n + min(-di, 0)), slice(max(-dj, 0), n + min(-dj, 0)))
        fresh.score[dst] = self.score[src]
        fresh.observed[dst] = self.observed[src]
        return fresh

    def index(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(ij, inside)``: grid indices of points (fixed frame), and which fall on the
        grid."""
        ij = _cell_of(points, self.cell) - np.asarray(self.corner)
        n = len(self.score)
        inside = np.all((ij >= 0) & (ij < n), axis=1)
        return ij, inside


def _cell_of(points: np.ndarray, cell: float) -> np.ndarray:
    return np.floor(points / cell).astype(np.int64)


def update_static_map(smap: StaticMap | None, sp: ScanPoints, pose: Pose2, dt: float, cfg,
                      protected: np.ndarray):
    """
    Learn from one scan; ``(map, background, learned)``: ``background`` a mask over
    ``sp.points`` (the returns on static structure or in unknown space), ``learned`` those
    that were not background by the map before this scan. ``protected`` (B,) marks the
    beams of protecting tracks; ``cfg`` is the background configuration.
    """
    smap = StaticMap.around(pose, cfg) if smap is None else smap.recentred(pose, cfg)
    ij, inside = smap.index(pose.to_outer(sp.points))
    before = _background(smap, ij, inside, protected[sp.beam], cfg.confirm_time)
    hit = np.zeros(smap.score.shape, bool)
    counts = inside & ~protected[sp.beam]
    hit[ij[counts, 0], ij[counts, 1]] = True
    crossed = _crossed(smap, sp, pose)
    behind = _behind(smap, sp, pose)
    freed = crossed & ~_box3(hit)
    score = smap.score.copy()
    cap = 2.0 * cfg.confirm_time
    score[hit] = np.minimum(score[hit] + dt, cap)
    score[freed] = np.maximum(score[freed] - dt, -cap)
    new = StaticMap(smap.corner, smap.cell, score, smap.observed | crossed | behind)
    background = _background(new, ij, inside, protected[sp.beam], cfg.confirm_time,
                             unknown=~smap.observed)
    return new, background, background & ~before


def _background(smap: StaticMap, ij: np.ndarray, inside: np.ndarray, protected: np.ndarray,
                confirm_time: float, unknown: np.ndarray | None = None) -> np.ndarray:
    """The returns (grid indices ``ij``) by static cells, or by cells ``unknown`` (by
    default: not yet observed) and not ``protected``; off the grid counts as unknown."""
    unknown = ~smap.observed if unknown is None else unknown
    static = smap.score >= OCCUPIED * confirm_time
    return _near(static, ij, inside) | (_near(unknown, ij, inside, off_grid=True) & ~protected)


def _behind(smap: StaticMap, sp: ScanPoints, pose: Pose2) -> np.ndarray:
    """The cells from one and a half cells to ``BEHIND`` beyond each return along its
    beam: the inside of what the beam hit (not its surface). Not unknown space: an
    object that stood still from start-up and then moves away from the scanner moves its
    near side into them."""
    r = sp.ranges[sp.beam]
    return _along(smap, pose, sp.angles[sp.beam], r + 1.5 * smap.cell, r + BEHIND)


def _along(smap: StaticMap, pose: Pose2, angles: np.ndarray, start: np.ndarray,
           stop: np.ndarray) -> np.ndarray:
    """The cells the beams at ``angles`` pass between the ranges ``start`` and
    ``stop``, sampled at 0.7 cell."""
    n = len(smap.score)
    out = np.zeros((n, n), bool)
    stop = np.minimum(stop, 0.5 * n * smap.cell)
    if not len(stop) or np.max(stop - start, initial=0.0) <= 0:
        return out
    step = 0.7 * smap.cell
    t = np.arange(0.0, np.max(stop - start), step)
    along = t[None, :] <= (stop - start)[:, None]
    heading = angles + pose.yaw
    reach = start[:, None] + t[None, :]
    x = pose.x + np.cos(heading)[:, None] * reach
    y = pose.y + np.sin(heading)[:, None] * reach
    ij, inside = smap.index(np.stack([x[along], y[along]], axis=1))
    out[ij[inside, 0], ij[inside, 1]] = True
    return out


def _crossed(smap: StaticMap, sp: ScanPoints, pose: Pose2) -> np.ndarray:
    """The cells the beams with a return crossed, well short of it: ``FREE_SHORT_CELLS``
    cells off the surface it hit, measured across the surface (a beam that grazes a wall
    runs along it, and would clear the wall's own cells)."""
    clear = FREE_SHORT_CELLS * smap.cell / np.maximum(_incidence(sp), 0.05)
    first = np.full(len(sp.beam), 0.7 * smap.cell)
    return _along(smap, pose, sp.angles[sp.beam], first, sp.ranges[sp.beam] - clear)


def _incidence(sp: ScanPoints) -> np.ndarray:
    """
    The sine of the angle at which each return's beam met the surface it hit, the
    surface taken towards each neighbouring beam's return (the smaller of the two: a
    grazing wall's neighbours lie far apart along it; at an edge the far side counts),
    1 (head on) where neither neighbour returned.
    """
    p, beam = sp.points, sp.beam
    out = np.ones(len(p))
    if len(p) < 2:
        return out
    d = p / np.maximum(np.hypot(p[:, 0], p[:, 1]), 1e-9)[:, None]
    step = p[1:] - p[:-1]
    length = np.maximum(np.hypot(step[:, 0], step[:, 1]), 1e-9)
    adjacent = np.diff(beam) == 1
    for rows, e in ((slice(1, None), d[1:]), (slice(None, -1), d[:-1])):
        sine = np.abs(e[:, 0] * step[:, 1] - e[:, 1] * step[:, 0]) / length
        out[rows] = np.where(adjacent, np.minimum(out[rows], sine), out[rows])
    return out


def _box3(a: np.ndarray) -> np.ndarray:
    """Whether each cell's 3 x 3 neighbourhood holds a True cell."""
    p = np.pad(a, 1)
    rows = p[:-2] | p[1:-1] | p[2:]
    return rows[:, :-2] | rows[:, 1:-1] | rows[:, 2:]


def _near(marked: np.ndarray, ij: np.ndarray, inside: np.ndarray,
          off_grid: bool = False) -> np.ndarray:
    """Which points (grid indices ``ij``) have a ``marked`` cell among their cell's 3 x 3
    (a point off the grid counts as near one when ``off_grid``)."""
    out = np.full(len(ij), off_grid)
    out[inside] = _box3(marked)[ij[inside, 0], ij[inside, 1]]
    return out


__all__ = ['StaticMap', 'update_static_map']
