"""
Pictures of a run (an edge module: it adds matplotlib, Agg backend, no display needed).

:func:`plot_run` draws a whole sequence: detections faint, background returns fainter,
each id's trajectory in its own colour with its last outline and label, the sensor and
its field of view. A :class:`RunSketch` gathers what it draws while a replay streams.
"""

from __future__ import annotations

from array import array
import math

import matplotlib

matplotlib.use('Agg')
from matplotlib.patches import Polygon, Wedge  # noqa: E402
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .messages import id_rgba, outline_xy  # noqa: E402


def id_colour(label: int):
    """The id's colour as RGB in 0..1: the same as its RViz markers."""
    c = id_rgba(label)
    return c['r'], c['g'], c['b']


def _outline(ax, row, colour, lw=1.5, alpha=1.0):
    """An object's outline at one scan (a RunSketch track row), as its RViz marker."""
    x, y, major, minor, yaw, rectangle = row.tolist()
    xy = outline_xy(np.array([x, y]), major, minor, yaw, bool(rectangle))
    ax.add_patch(Polygon(xy, closed=True, fill=False, ec=colour, lw=lw, alpha=alpha))


def _sensor(ax, angle_lo, angle_hi, range_max, pose=(0.0, 0.0, 0.0)):
    """The field of view of the scanner at ``pose`` (x, y, yaw), and the scanner."""
    x, y, yaw = pose
    ax.add_patch(Wedge((x, y), range_max, math.degrees(angle_lo + yaw),
                       math.degrees(angle_hi + yaw), fc=(0.93, 0.95, 1.0),
                       ec=(0.6, 0.65, 0.8), lw=0.8, zorder=0))
    ax.plot([x], [y], marker='^', color='k', ms=8, zorder=5)


def _path(ax, path: np.ndarray, label: bool = True) -> None:
    """A scanner's path in the fixed frame."""
    ax.plot(path[:, 0], path[:, 1], '-', color='k', lw=1.0, alpha=0.7,
            label='sensor path' if label else None, zorder=4)


class RunSketch:
    """
    What :func:`plot_run` draws of a run, gathered scan by scan in bounded memory.

    Keeps each id's track (centre and outline per scan: six floats) and a sample of the
    detection and background clouds: every ``stride``-th scan's, the stride doubling
    whenever the sample passes ``2 * max_points`` points, each scan counted as
    ``SCAN_COST`` points more (its entry and two array headers take about 350 bytes, as
    much as 22 points). A bag of hours would otherwise keep every return of every scan
    until the end. Runs under the budget keep all.
    """

    SCAN_COST = 24

    def __init__(self, is_rectangle=None, max_points: int = 200_000):
        self.is_rectangle = is_rectangle
        self.max_points = max_points
        self.scans = 0
        self.tracks: dict = {}            # label -> x, y, major, minor, yaw, rectangle, ...
        self.stride = 1
        self.clouds: list = []           # (scan index, detections, background returns)
        self._kept = 0
        self.paths: dict = {}            # scanner -> its x, y, yaw in the fixed frame

    def add(self, result) -> None:
        """Take one :class:`StepResult`."""
        e = result.estimates
        if len(e):
            major, minor, yaw = e.axes()
            rect = (self.is_rectangle(e) if self.is_rectangle is not None
                    else np.zeros(len(e), dtype=bool))
            rows = zip(e.label.tolist(), e.m[:, :2].tolist(), major.tolist(), minor.tolist(),
                       yaw.tolist(), rect.tolist())
            for lab, (x, y), a, b, w, r in rows:
                track = self.tracks.get(lab)
                if track is None:
                    track = self.tracks[lab] = array('d')
                track.extend((x, y, a, b, w, float(r)))
        k, self.scans = self.scans, self.scans + 1
        pose = getattr(result, 'pose', None)
        if pose is not None:
            key = getattr(result, 'scanner', None) or ''
            self.paths.setdefault(key, array('d')).extend((pose.x, pose.y, pose.yaw))
        pts, bg = result.points, result.background_points
        if k % self.stride or not (len(pts) or len(bg)):
            return
        self.clouds.append((k, np.array(pts), np.array(bg)))
        self._kept += len(pts) + len(bg) + self.SCAN_COST
        while self._kept > 2 * self.max_points and len(self.clouds) > 1:
            self.stride *= 2
            self.clouds = [c for c in self.clouds if c[0] % self.stride == 0]
            self._kept = sum(len(c[1]) + len(c[2]) + self.SCAN_COST for c in self.clouds)

    def track(self, label) -> np.ndarray:
        """Label's rows ``(x, y, major, minor, yaw, rectangle)``, one per scan it was in."""
        return np.array(self.tracks[label], dtype=np.float64).reshape(-1, 6)

    def points(self) -> list:
        """The sampled scans' detection arrays (non-empty ones)."""
        return [c[1] for c in self.clouds if len(c[1])]

    def background(self) -> list:
        """The sampled scans' background arrays (non-empty ones)."""
        return [c[2] for c in self.clouds if len(c[2])]


def plot_run(results, path, title='', fov=None, is_rectangle=None, max_points=200_000,
             min_scans=10):
    """
    Draw a run into a PNG.

    Parameters
    ----------
    results : list of StepResult, or a RunSketch of them
    path : str or Path
    fov : (angle_lo, angle_hi, range_max), or {scanner frame: that}, optional
        Field of view to shade (of each scanner, at its last pose).
    is_rectangle : callable, optional
        ``is_rectangle(estimates) -> bool array``: which outlines to draw as boxes. Unused
        when ``results`` is a RunSketch, which applied its own while gathering.
    max_points : int
        The detections (and the background returns) are drawn thinned to every k-th,
        ``k = their number // max_points``: between ``max_points`` and twice as many
        when there are more. Also the sketch's budget when ``results`` is a list (it
        keeps at most twice this many of each).
    min_scans : int
        Ids reported in fewer scans are drawn as faint grey traces without outlines.

    """
    sketch = results
    if not isinstance(sketch, RunSketch):
        sketch = RunSketch(is_rectangle, max_points)
        for r in results:
            sketch.add(r)
    pts, bg = sketch.points(), sketch.background()
    tracks = {lab: sketch.track(lab) for lab in sorted(sketch.tracks)}
    paths = {k: np.array(v).reshape(-1, 3) for k, v in sketch.paths.items()}
    origin = next(iter(paths.values()))[-1, :2] if paths else np.zeros(2)
    limits = plot_limits(pts + [seq[:, :2] for seq in tracks.values()]
                         + [p[:, :2] for p in paths.values()], origin=origin)
    fig, ax = plt.subplots(figsize=figure_size(limits), dpi=110)
    fovs = fov if isinstance(fov, dict) else {k: fov for k in paths or ['']}
    for key, view in fovs.items():
        if view is not None:
            last = paths[key][-1] if key in paths else (0.0, 0.0, 0.0)
            _sensor(ax, *view, pose=tuple(last))
    for k, poses in enumerate(paths.values()):
        _path(ax, poses, label=k == 0)
    if bg:
        b = np.vstack(bg)
        step = max(1, len(b) // max_points)
        ax.scatter(b[::step, 0], b[::step, 1], s=0.3, c='0.8', lw=0, label='background')
    if pts:
        p = np.vstack(pts)
        step = max(1, len(p) // max_points)
        ax.scatter(p[::step, 0], p[::step, 1], s=0.6, c='0.45', lw=0, alpha=0.5,
                   label='detections')
    short = 0
    for lab, seq in tracks.items():
        col = id_colour(lab)
        xy = seq[:, :2]
        if len(seq) < min_scans:
            # short-lived ids: a faint trace only, so long tracks stay readable
            short += 1
            ax.plot(xy[:, 0], xy[:, 1], '-', color='0.55', lw=0.5, alpha=0.6)
            continue
        ax.plot(xy[:, 0], xy[:, 1], '-', color=col, lw=1.2, alpha=0.9)
        # a few outlines along the way, the last one bold with the id
        every = max(1, len(seq) // 6)
        for s in seq[::every]:
            _outline(ax, s, col, lw=0.8, alpha=0.5)
        _outline(ax, seq[-1], col, lw=2.0)
        ax.annotate(str(lab), xy[-1], xytext=(4, 4), textcoords='offset points', color=col,
                    fontsize=9, weight='bold')
    ax.set_aspect('equal')
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    ax.set_title((title or f'{sketch.scans} scans, {len(sketch.tracks)} ids')
                 + f'\n(grey: {short} ids reported in fewer than {min_scans} scans)')
    if pts or bg:
        ax.legend(loc='upper right', fontsize=8, markerscale=10)
    if limits is not None:
        ax.set_xlim(limits[0][0], limits[1][0])
        ax.set_ylim(limits[0][1], limits[1][1])
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_limits(chunks, origin=np.zeros(2)):
    """``(lo, hi)`` corners of the view around the points and track centres (0.5 and 99.5
    percentiles, 1 m margin), the sensor at ``origin`` kept in view, half a metre from
    the edge at least, on every side (a scanner looking backwards sees negative x only);
    None without any."""
    chunks = [c for c in chunks if len(c)]
    if not chunks:
        return None
    allp = np.vstack(chunks + [origin[None, :]])
    lo = np.percentile(allp, 0.5, axis=0) - 1.0
    hi = np.percentile(allp, 99.5, axis=0) + 1.0
    return np.minimum(lo, origin - 0.5), np.maximum(hi, origin + 0.5)


FIGURE_SIZE = (10.0, 8.0)        # inches, the picture of a scene about as wide as deep
FIGURE_SIDE_MAX = 16.0           # the width of a picture of a wide, shallow scene
FIGURE_DEPTH_MAX = 10.0          # the height of a picture of a deep, narrow one
FIGURE_SIDE_MIN = 4.0
FIGURE_FRAME = (1.2, 1.3)        # inches of labels and title around the axes (w, h)


def figure_size(limits):
    """
    Figure size for the view ``limits`` drawn at equal scale: 10 x 8 inches for a view
    within a factor of two of that box's proportions, else the long side stretched (to
    ``FIGURE_SIDE_MAX`` across, ``FIGURE_DEPTH_MAX`` down) and the short side fitted to
    the view (a corridor 22 m long and 4.5 m wide filled a strip of the 10 x 8 inches
    under two inches high).
    """
    if limits is None:
        return FIGURE_SIZE
    width, depth = np.maximum(limits[1] - limits[0], 1e-6)
    fw, fh = FIGURE_FRAME
    ratio = depth / width
    box_w, box_h = FIGURE_SIZE[0] - fw, FIGURE_SIZE[1] - fh
    if box_h / box_w * 0.5 <= ratio <= box_h / box_w * 2.0:
        return FIGURE_SIZE
    if ratio < 1.0:                                   # wide: long side across
        w = FIGURE_SIDE_MAX
        h = min(max((w - fw) * ratio + fh, FIGURE_SIDE_MIN), FIGURE_SIZE[1])
    else:                                             # deep: long side down
        h = FIGURE_DEPTH_MAX
        w = min(max((h - fh) / ratio + fw, FIGURE_SIDE_MIN), FIGURE_SIZE[0])
    return float(w), float(h)
