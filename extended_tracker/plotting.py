"""
Pictures of a run (an edge module: it adds matplotlib, Agg backend, no display needed).

:func:`plot_run` draws a whole sequence: detections faint, background returns fainter,
each id's trajectory in its own colour with its last outline and label, the sensor and
its field of view.
"""

from __future__ import annotations

import math

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Polygon, Wedge  # noqa: E402
import numpy as np  # noqa: E402

from .messages import id_rgba, outline_xy  # noqa: E402


def id_colour(label: int):
    """The id's colour as RGB in 0..1: the same as its RViz markers."""
    c = id_rgba(label)
    return c['r'], c['g'], c['b']


def _outline(ax, estimates, j, colour, rectangle=False, lw=1.5, alpha=1.0):
    """Object ``j``'s outline, the same polygon as its RViz marker."""
    major, minor, yaw = estimates.axes()
    xy = outline_xy(estimates.m[j, :2], major[j], minor[j], yaw[j], rectangle)
    ax.add_patch(Polygon(xy, closed=True, fill=False, ec=colour, lw=lw, alpha=alpha))


def _sensor(ax, angle_lo, angle_hi, range_max):
    ax.add_patch(Wedge((0, 0), range_max, math.degrees(angle_lo), math.degrees(angle_hi),
                       fc=(0.93, 0.95, 1.0), ec=(0.6, 0.65, 0.8), lw=0.8, zorder=0))
    ax.plot([0], [0], marker='^', color='k', ms=8, zorder=5)


def plot_run(results, path, title='', fov=None, is_rectangle=None, max_points=200_000,
             min_scans=10):
    """
    Draw a sequence of :class:`StepResult` into a PNG.

    Parameters
    ----------
    results : list of StepResult
    path : str or Path
    fov : (angle_lo, angle_hi, range_max), optional
        Field of view to shade.
    is_rectangle : callable, optional
        ``is_rectangle(estimates) -> bool array``: which outlines to draw as boxes.
    min_scans : int
        Ids reported in fewer scans are drawn as faint grey traces without outlines.

    """
    fig, ax = plt.subplots(figsize=(10, 8), dpi=110)
    if fov is not None:
        _sensor(ax, *fov)
    pts = [r.points for r in results if len(r.points)]
    bg = [r.background_points for r in results if len(r.background_points)]
    if bg:
        b = np.vstack(bg)
        step = max(1, len(b) // max_points)
        ax.scatter(b[::step, 0], b[::step, 1], s=0.3, c='0.8', lw=0, label='background')
    if pts:
        p = np.vstack(pts)
        step = max(1, len(p) // max_points)
        ax.scatter(p[::step, 0], p[::step, 1], s=0.6, c='0.45', lw=0, alpha=0.5,
                   label='detections')
    tracks = {}
    for r in results:
        e = r.estimates
        for j, lab in enumerate(e.label.tolist()):
            tracks.setdefault(lab, []).append((e.m[j, :2], r, j))
    short = 0
    for lab, seq in sorted(tracks.items()):
        col = id_colour(lab)
        xy = np.array([s[0] for s in seq])
        if len(seq) < min_scans:
            # short-lived ids: a faint trace only, so long tracks stay readable
            short += 1
            ax.plot(xy[:, 0], xy[:, 1], '-', color='0.55', lw=0.5, alpha=0.6)
            continue
        ax.plot(xy[:, 0], xy[:, 1], '-', color=col, lw=1.2, alpha=0.9)
        # a few outlines along the way, the last one bold with the id
        every = max(1, len(seq) // 6)
        for _, r, j in seq[::every]:
            rect = bool(is_rectangle(r.estimates)[j]) if is_rectangle else False
            _outline(ax, r.estimates, j, col, rectangle=rect, lw=0.8, alpha=0.5)
        m, r, j = seq[-1]
        rect = bool(is_rectangle(r.estimates)[j]) if is_rectangle else False
        _outline(ax, r.estimates, j, col, rectangle=rect, lw=2.0)
        ax.annotate(str(lab), m, xytext=(4, 4), textcoords='offset points', color=col,
                    fontsize=9, weight='bold')
    ax.set_aspect('equal')
    ax.set_xlabel('x (m)')
    ax.set_ylabel('y (m)')
    n_scans = len(results)
    ax.set_title((title or f'{n_scans} scans, {len(tracks)} ids')
                 + f'\n(grey: {short} ids reported in fewer than {min_scans} scans)')
    if pts or bg:
        ax.legend(loc='upper right', fontsize=8, markerscale=10)
    _fit(ax, results, fov)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _fit(ax, results, fov):
    chunks = [r.points for r in results if len(r.points)]
    chunks += [r.estimates.m[:, :2] for r in results if len(r.estimates)]
    if not chunks:
        return
    allp = np.vstack(chunks + [np.zeros((1, 2))])
    lo = np.percentile(allp, 0.5, axis=0) - 1.0
    hi = np.percentile(allp, 99.5, axis=0) + 1.0
    lo = np.minimum(lo, -0.5)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
