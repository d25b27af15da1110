"""
A transform buffer for planar tracking: what tf2's ``Buffer`` does, for a venv that has
no tf2.

Transforms (parent -> child, a translation and a unit quaternion, at a stamp) are fed in
from ``/tf`` and ``/tf_static`` messages or a bag. :meth:`TransformBuffer.lookup` gives
``target <- source`` at a time: each link of the chain through the tree interpolated at
that time (translations linearly, rotations by slerp), static links at any time. A time
outside a link's data is an :class:`ExtrapolationError` (``future`` when the data may still
come); frames that are not linked, a :class:`ConnectivityError`. :func:`planar` projects
the result onto the plane, refusing a mount tilted more than allowed
(:class:`TiltError`).
"""

from __future__ import annotations

from bisect import bisect_left, insort
from dataclasses import dataclass
import math

import numpy as np

from .pose import Pose2

#: how long dynamic transforms are kept, ns (tf2's default cache time: 10 s)
CACHE_NS = 10_000_000_000


class TransformError(LookupError):
    """No transform between the frames at the time asked."""


class ConnectivityError(TransformError):
    """The frames are not linked (one is unknown, or they are in different trees)."""


class ExtrapolationError(TransformError):
    """The time asked is outside the data of a link; ``future`` when it is after the
    newest data (waiting may help)."""

    def __init__(self, text: str, future: bool):
        super().__init__(text)
        self.future = future


class TiltError(TransformError):
    """The scan plane is tilted from the fixed frame's plane more than allowed."""


@dataclass(frozen=True)
class Transform:
    """A rigid transform: ``translation`` (3,) and rotation ``quaternion`` (x, y, z, w)."""

    translation: np.ndarray
    quaternion: np.ndarray

    @staticmethod
    def identity() -> 'Transform':
        return Transform(np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]))

    def compose(self, other: 'Transform') -> 'Transform':
        """``self * other``."""
        t = self.translation + rotate(self.quaternion, other.translation)
        return Transform(t, quat_mul(self.quaternion, other.quaternion))

    def inverse(self) -> 'Transform':
        q = self.quaternion * np.array([-1.0, -1.0, -1.0, 1.0])
        return Transform(-rotate(q, self.translation), q)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product of quaternions (x, y, z, w)."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def rotation_matrix(q: np.ndarray) -> np.ndarray:
    """(3, 3) rotation of a unit quaternion (x, y, z, w)."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    return rotation_matrix(q) @ v


def slerp(a: np.ndarray, b: np.ndarray, s: float) -> np.ndarray:
    """The rotation ``s`` of the way from ``a`` to ``b`` (the shorter way round)."""
    dot = float(a @ b)
    if dot < 0.0:
        b, dot = -b, -dot
    if dot > 0.9995:                    # nearly equal: linear, then normalised
        q = a + s * (b - a)
    else:
        theta = math.acos(dot)
        q = (math.sin((1 - s) * theta) * a + math.sin(s * theta) * b) / math.sin(theta)
    return q / np.linalg.norm(q)


def planar(tf: Transform, max_tilt: float) -> Pose2:
    """
    The planar pose of a transform: its translation's x and y, and the heading of its x
    axis projected onto the plane. Refused (:class:`TiltError`) when its z axis leans more
    than ``max_tilt`` radians from the vertical: a scan plane that tilted is not the
    ground plane, and its returns would be placed wrongly at any range.
    """
    R = rotation_matrix(tf.quaternion)
    tilt = math.acos(min(max(R[2, 2], -1.0), 1.0))
    if tilt > max_tilt:
        raise TiltError(f'the scan plane is tilted {math.degrees(tilt):.1f} deg from the '
                        f'fixed frame\'s plane, over tf.max_tilt '
                        f'({math.degrees(max_tilt):.1f} deg)')
    return Pose2(float(tf.translation[0]), float(tf.translation[1]),
                 math.atan2(R[1, 0], R[0, 0]))


class _Link:
    """The transforms of one child frame from its parent: static, or stamped samples."""

    def __init__(self, parent: str, static: bool, cache_ns: int | None):
        self.parent, self.static, self.cache_ns = parent, static, cache_ns
        self.stamps: list[int] = []
        self.samples: dict[int, Transform] = {}

    def add(self, stamp_ns: int, tf: Transform) -> None:
        if self.static:
            self.stamps, self.samples = [0], {0: tf}
            return
        if stamp_ns not in self.samples:
            insort(self.stamps, stamp_ns)
        self.samples[stamp_ns] = tf
        if self.cache_ns is None:
            return
        cut = bisect_left(self.stamps, self.stamps[-1] - self.cache_ns)
        for old in self.stamps[:cut]:
            del self.samples[old]
        del self.stamps[:cut]

    def at(self, stamp_ns: int, child: str) -> Transform:
        if self.static:
            return self.samples[0]
        i = bisect_left(self.stamps, stamp_ns)
        if i < len(self.stamps) and self.stamps[i] == stamp_ns:
            return self.samples[stamp_ns]
        if i == 0 or i == len(self.stamps):
            future = i == len(self.stamps)
            edge = self.stamps[-1] if future else self.stamps[0]
            raise ExtrapolationError(
                f'{self.parent} -> {child} is known from {self.stamps[0] * 1e-9:.3f} s to '
                f'{self.stamps[-1] * 1e-9:.3f} s; asked at {stamp_ns * 1e-9:.3f} s, '
                f'{abs(stamp_ns - edge) * 1e-9:.3f} s {"after" if future else "before"} '
                f'that', future)
        t0, t1 = self.stamps[i - 1], self.stamps[i]
        a, b = self.samples[t0], self.samples[t1]
        s = (stamp_ns - t0) / (t1 - t0)
        return Transform(a.translation + s * (b.translation - a.translation),
                         slerp(a.quaternion, b.quaternion, s))


class TransformBuffer:
    """
    Stamped and static transforms between frames, looked up at a time. Dynamic ones are
    kept ``cache_ns`` (all of them with None: a bag replayed offline).
    """

    def __init__(self, cache_ns: int | None = CACHE_NS):
        self._links: dict[str, _Link] = {}
        self.cache_ns = cache_ns

    def set_transform(self, parent: str, child: str, stamp_ns: int, translation,
                      quaternion, static: bool = False) -> None:
        """Add ``parent -> child`` at ``stamp_ns`` (any time when ``static``). A child
        given a new parent, or turned static or dynamic, starts over."""
        parent, child = parent.lstrip('/'), child.lstrip('/')
        if not parent or not child or parent == child:
            raise ValueError(f'a transform needs two distinct frames, got {parent!r} -> '
                             f'{child!r}')
        q = np.asarray(quaternion, dtype=float)
        t = np.asarray(translation, dtype=float)
        norm = float(np.linalg.norm(q))
        if not (np.isfinite(q).all() and np.isfinite(t).all() and norm > 0.0):
            raise ValueError(f'{parent} -> {child}: a non-finite translation or a zero '
                             'quaternion')
        link = self._links.get(child)
        if link is None or link.parent != parent or link.static != static:
            link = self._links[child] = _Link(parent, static, self.cache_ns)
        link.add(int(stamp_ns), Transform(t, q / norm))

    def frames(self) -> set[str]:
        return set(self._links) | {link.parent for link in self._links.values()}

    def _chain(self, frame: str) -> list[str]:
        """``frame`` and its ancestors up to the root."""
        chain = [frame]
        while chain[-1] in self._links and len(chain) <= len(self._links):
            chain.append(self._links[chain[-1]].parent)
        return chain

    def _to_ancestor(self, chain: list[str], stamp_ns: int) -> Transform:
        """``chain[-1] <- chain[0]``: the links along the chain composed."""
        tf = Transform.identity()
        for child in reversed(chain[:-1]):
            tf = tf.compose(self._links[child].at(stamp_ns, child))
        return tf

    def lookup(self, target: str, source: str, stamp_ns: int) -> Transform:
        """``target <- source`` at ``stamp_ns``: maps points in ``source`` into ``target``."""
        target, source = target.lstrip('/'), source.lstrip('/')
        up_source, up_target = self._chain(source), self._chain(target)
        common = next((f for f in up_source if f in up_target), None)
        if common is None or (source != target and source not in self.frames()):
            raise ConnectivityError(f'no transform links {source!r} to {target!r} (known '
                                    f'frames: {", ".join(sorted(self.frames())) or "none"})')
        s_part = up_source[:up_source.index(common) + 1]
        t_part = up_target[:up_target.index(common) + 1]
        return self._to_ancestor(t_part, stamp_ns).inverse().compose(
            self._to_ancestor(s_part, stamp_ns))

    def can_link(self, target: str, source: str) -> bool:
        """Whether the frames are linked at all (at some time)."""
        try:
            self.lookup(target, source, 0)
        except ExtrapolationError:
            return True
        except ConnectivityError:
            return False
        return True


__all__ = ['TransformBuffer', 'Transform', 'planar', 'TransformError', 'ConnectivityError',
           'ExtrapolationError', 'TiltError', 'CACHE_NS']
