"""
What each scanner keeps of its own, for the pipeline: its per-beam background, where
that was learned, and its last pose in the fixed frame. Scanners placed in one fixed
frame update one filter; each is judged against its own background and its own last
pose.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math
from typing import TYPE_CHECKING

import numpy as np

from .frames.pose import Pose2
from .sensing.background import BackgroundState

if TYPE_CHECKING:                                   # the pipeline imports these helpers
    from .pipeline import PipelineState

#: the scanner moved less than this from where the per-beam background was learned (m,
#: rad) still stands there: odometry's jitter on a parked robot does not reset it
STILL_DISTANCE = 0.05
STILL_ANGLE = 0.01


@dataclass(frozen=True)
class View:
    """Where a scanner looked in its last scan: its pose in the fixed frame and its
    field of view (rad, in its own frame) out to its range (m)."""

    pose: Pose2
    angle_lo: float
    angle_hi: float
    range_max: float
    full_turn: bool

    def sees(self, xy: np.ndarray) -> np.ndarray:
        """Which of the points ``xy`` (fixed frame) lie in this field of view."""
        p = self.pose.to_inner(xy)
        near = np.hypot(p[:, 0], p[:, 1]) <= self.range_max
        if self.full_turn:
            return near
        bearing = np.arctan2(p[:, 1], p[:, 0])
        mid = 0.5 * (self.angle_lo + self.angle_hi)
        off = np.abs((bearing - mid + math.pi) % (2 * math.pi) - math.pi)
        return near & (off <= 0.5 * (self.angle_hi - self.angle_lo))


def seen_elsewhere(state: 'PipelineState', xy: np.ndarray) -> np.ndarray | None:
    """Which of the points ``xy`` (fixed frame) another scanner, not silent, looked at in
    its last scan; None with one scanner."""
    views = [sc.view for sc in state.others.values()
             if sc.view is not None and not sc.silent]
    if not views:
        return None
    return np.any([v.sees(xy) for v in views], axis=0)


@dataclass(frozen=True)
class Scanner:
    """What each scanner keeps of its own: its per-beam background, where that was
    learned, and its last pose and stamp in the fixed frame."""

    background: BackgroundState | None = None
    anchor: Pose2 | None = None
    pose: Pose2 | None = None
    pose_ns: int | None = None
    view: View | None = None
    silent: bool = False


def silenced(state: 'PipelineState', now_ns: int, max_gap: float):
    """
    ``(state, frames)``: the other scanners whose last scan is more than ``max_gap``
    older than ``now_ns`` marked silent (their field of view no longer keeps what this
    scanner cannot see), and those newly so. A scanner that comes back is heard again
    (:func:`with_scanner`).
    """
    quiet = [f for f, sc in state.others.items() if not sc.silent and sc.pose_ns is not None
             and (now_ns - sc.pose_ns) * 1e-9 > max_gap]
    if not quiet:
        return state, []
    others = {f: replace(sc, silent=True) if f in quiet else sc
              for f, sc in state.others.items()}
    return replace(state, others=others), sorted(quiet)


def with_scanner(state: 'PipelineState', frame: str):
    """
    ``(state, last_ns)``: the state with scanner ``frame``'s own parts in ``background``,
    ``anchor`` and ``pose``, the current scanner's put aside, and the stamp of that
    scanner's last scan. Each scanner placed in the fixed frame learns its own
    background and is checked for jumps against its own last pose.
    """
    if state.scanner in (None, frame):
        return replace(state, scanner=frame), state.last_stamp_ns
    others = dict(state.others)
    others[state.scanner] = Scanner(state.background, state.anchor, state.pose,
                                    state.last_stamp_ns, state.view)
    mine = others.pop(frame, Scanner())
    return replace(state, scanner=frame, others=others, background=mine.background,
                   anchor=mine.anchor, pose=mine.pose, view=mine.view), mine.pose_ns


#: scans between two checks of the scanners' mounts against each other
MOUNT_CHECK_SCANS = 100
#: the median gap (m) between two scanners' views of the same static structure above
#: which their mounts disagree
MOUNT_TOLERANCE = 0.1
#: returns of two scanners this near (m) see the same structure; fewer than
#: MOUNT_OVERLAP such pairs say nothing
MOUNT_NEAR, MOUNT_OVERLAP = 0.5, 30


def background_points(background: BackgroundState | None, anchor: Pose2 | None):
    """The static returns a scanner's per-beam background learned, in the fixed frame."""
    if background is None or anchor is None:
        return np.zeros((0, 2))
    known = np.isfinite(background.background)
    r, a = background.background[known], background.angles[known]
    return anchor.to_outer(np.column_stack([r * np.cos(a), r * np.sin(a)]))


def mount_disagreement(state: 'PipelineState') -> tuple[float, str] | None:
    """
    ``(gap, pair)``: the largest, over pairs of scanners, median distance from one's
    learned static returns to the other's nearest, where both see the same structure
    (within ``MOUNT_NEAR``); None with fewer than two scanners or too little overlap.
    Scanners placed right see a wall where the other does (a few centimetres: noise and
    beam spacing); a mount off by a few degrees puts it tens of centimetres apart.
    """
    from scipy.spatial import cKDTree

    views = {state.scanner: background_points(state.background, state.anchor)}
    views.update({f: background_points(sc.background, sc.anchor)
                  for f, sc in state.others.items()})
    worst = None
    names = sorted(f for f, p in views.items() if len(p))
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            d, _ = cKDTree(views[b]).query(views[a], distance_upper_bound=MOUNT_NEAR)
            d = d[np.isfinite(d)]
            if len(d) >= MOUNT_OVERLAP and (worst is None or np.median(d) > worst[0]):
                worst = (float(np.median(d)), f'{a} and {b}')
    return worst


def mount_check(state: 'PipelineState') -> tuple['PipelineState', str | None]:
    """
    ``(state, reason)``: every ``MOUNT_CHECK_SCANS`` scans of several scanners, whether
    their mounts disagree with what they show (:func:`mount_disagreement` over
    ``MOUNT_TOLERANCE``); said once (the reason of event ``mount_mismatch``), None
    otherwise.
    """
    if not state.others or state.mount_mismatch or state.scans % MOUNT_CHECK_SCANS:
        return state, None
    worst = mount_disagreement(state)
    if worst is None or worst[0] <= MOUNT_TOLERANCE:
        return state, None
    return replace(state, mount_mismatch=True), (
        f'{worst[1]} see the same static structure {worst[0]:.2f} m apart (median): '
        f'their mounts (TF or the mounts given) disagree with the scans')


def anchored(state: 'PipelineState', pose: Pose2 | None, jumped: bool):
    """
    ``(state, leaving)``: the state anchored where the scanner stands, and whether it
    has just left the place its per-beam background was learned at. That background
    still judges this scan (it is a few centimetres off: it seeds the static map, which
    is put to use from now on) and is learned anew from the next. After a jump of the
    fixed frame the scanner stands where it stood, but the static map, learned in the
    old frame, is dropped.
    """
    if pose is None:
        return state, False
    if jumped:
        return replace(state, anchor=pose, static_map=None), False
    if state.anchor is None:
        return replace(state, anchor=pose), False
    metres, radians = state.anchor.distance_to(pose)
    if metres <= STILL_DISTANCE and radians <= STILL_ANGLE:
        return state, False
    return replace(state, anchor=pose, moving=True), True


__all__ = ['Scanner', 'View', 'seen_elsewhere', 'silenced', 'mount_disagreement', 'mount_check', 'with_scanner', 'anchored', 'STILL_DISTANCE', 'STILL_ANGLE']
