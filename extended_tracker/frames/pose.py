"""
A planar rigid pose (x, y, yaw) and what the pipeline moves with it: points between the
scanner's frame and the fixed frame, and the filter's components into the scanner's
frame, where the detection model reads its polar geometry.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
import math

import numpy as np


@dataclass(frozen=True)
class Pose2:
    """
    A frame's pose in another (the scanner's in the fixed frame, say): its origin
    ``(x, y)`` in metres and its heading ``yaw`` in radians.
    """

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0

    @property
    def is_identity(self) -> bool:
        return self.x == 0.0 and self.y == 0.0 and self.yaw == 0.0

    @property
    def rotation(self) -> np.ndarray:
        """(2, 2) rotation from the frame's axes to the other's."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array([[c, -s], [s, c]])

    @property
    def origin(self) -> np.ndarray:
        return np.array([self.x, self.y])

    def compose(self, other: 'Pose2') -> 'Pose2':
        """``self * other``: the pose of a frame posed at ``other`` in this one."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose2(self.x + c * other.x - s * other.y, self.y + s * other.x + c * other.y,
                     wrap_angle(self.yaw + other.yaw))

    def inverse(self) -> 'Pose2':
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose2(-c * self.x - s * self.y, s * self.x - c * self.y, -self.yaw)

    def to_outer(self, points: np.ndarray) -> np.ndarray:
        """(n, 2) points given in this frame, in the outer one."""
        if self.is_identity:
            return points
        return points @ self.rotation.T + self.origin

    def to_inner(self, points: np.ndarray) -> np.ndarray:
        """(n, 2) points given in the outer frame, in this one."""
        if self.is_identity:
            return points
        return (points - self.origin) @ self.rotation

    def vectors_to_outer(self, vectors: np.ndarray) -> np.ndarray:
        """(n, 2) directions or offsets given in this frame, in the outer one."""
        return vectors if self.is_identity else vectors @ self.rotation.T

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        """``(x, y, z, w)`` of the heading: a turn of ``yaw`` about the vertical."""
        return 0.0, 0.0, math.sin(self.yaw / 2), math.cos(self.yaw / 2)

    def distance_to(self, other: 'Pose2') -> tuple[float, float]:
        """How far apart two poses are: metres, and radians of heading."""
        return (math.hypot(other.x - self.x, other.y - self.y),
                abs(wrap_angle(other.yaw - self.yaw)))


@dataclass(frozen=True)
class Placement:
    """Where a scan was taken: the fixed ``frame`` and the scanner's ``pose`` in it at the
    scan's stamp."""

    frame: str
    pose: Pose2


def wrap_angle(a: float) -> float:
    """``a`` in [-pi, pi)."""
    return (a + math.pi) % (2 * math.pi) - math.pi


def kinematics_to_inner(pose: Pose2, m: np.ndarray, P: np.ndarray, V: np.ndarray | None):
    """
    Kinematic means ``m`` (k, 4), covariances ``P`` (k, 4, 4) and extent scales ``V``
    (k, 2, 2) given in the outer frame, in the frame at ``pose``: positions moved and
    rotated, velocities, covariances and extents rotated. The velocities stay those over
    the ground, only their axes turn (the detection model reads positions and extents).
    """
    if pose.is_identity:
        return m, P, V
    R = pose.rotation
    T = np.zeros((4, 4))
    T[:2, :2] = T[2:, 2:] = R.T
    m_in = m @ T.T
    m_in[:, :2] -= pose.origin @ R
    return m_in, T @ P @ T.T, None if V is None else R.T @ V @ R


def mixture_to_inner(pose: Pose2, mix):
    """A :class:`filter.mixture.Mixture` (or anything with ``m``, ``P`` and ``V``) seen
    from the frame at ``pose``."""
    m, P, V = kinematics_to_inner(pose, mix.m, mix.P, mix.V)
    return mix if m is mix.m else replace(mix, m=m, P=P, V=V)


__all__ = ['Pose2', 'Placement', 'wrap_angle', 'kinematics_to_inner', 'mixture_to_inner']
