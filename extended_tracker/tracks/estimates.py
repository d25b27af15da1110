"""
What one scan reports: :class:`Estimates`, the objects shown, arrays with a leading
object axis (what the node publishes and the replay writes).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..filter.algebra2 import eig2
from ..filter.tables import read_only


@dataclass(frozen=True)
class Estimates:
    """
    Reported objects of one scan, arrays with a leading object axis of length ``k``.

    Attributes
    ----------
    label : (k,) int64
    existence : (k,) weight of the label, clipped to [0, 1]
    m : (k, 4) kinematic mean; P : (k, 4, 4) its covariance
    X : (k, 2, 2) expected extent matrix (m^2)
    rate : (k,) expected detections per scan
    num_detections : (k,) detections that updated the label this scan
    visibility : (k,) visible fraction used for p_D (1 where not computed)

    """

    label: np.ndarray
    existence: np.ndarray
    m: np.ndarray
    P: np.ndarray
    X: np.ndarray
    rate: np.ndarray
    num_detections: np.ndarray
    visibility: np.ndarray

    def __len__(self):
        return int(self.label.shape[0])

    def take(self, idx) -> 'Estimates':
        """The objects at ``idx`` (index array or boolean mask)."""
        return Estimates(self.label[idx], self.existence[idx], self.m[idx],
                         self.P[idx], self.X[idx], self.rate[idx],
                         self.num_detections[idx], self.visibility[idx])

    def axes(self):
        """Semi-major, semi-minor (m) and yaw of the major axis (rad) of each extent."""
        return self._axes

    @cached_property
    def _axes(self):
        # computed once per scan's estimates, read by messages, markers, shapes and plots
        # (shared, so read-only)
        lam1, lam2 = eig2(self.X)
        yaw = 0.5 * np.arctan2(2 * self.X[:, 0, 1], self.X[:, 0, 0] - self.X[:, 1, 1])
        return read_only(np.sqrt(lam1), np.sqrt(np.maximum(lam2, 0.0)), yaw)

    def rectangle(self):
        """
        Length and width of the oriented rectangle with the ellipse's second moments.

        Notes
        -----
        A filled ellipse of semi-axis ``a`` has second moment ``a^2/4`` along it; a filled
        rectangle of side ``L`` has ``L^2/12``; equal moments give ``L = sqrt(3) a``.
        """
        major, minor, _ = self.axes()
        return np.sqrt(3.0) * major, np.sqrt(3.0) * minor

    @staticmethod
    def empty():
        """Return estimates with no object."""
        return Estimates(np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 4)),
                         np.zeros((0, 4, 4)), np.zeros((0, 2, 2)), np.zeros(0),
                         np.zeros(0, np.int64), np.zeros(0))
