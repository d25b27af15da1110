"""
How far each reported id has been from where it was first reported: the count of ids
that moved, which the replay's summary and the people-counting table give.
"""

from __future__ import annotations

import numpy as np

from .estimates import Estimates

MOVED = 1.0          # m: an id that has been farther than this from where it was first shown


class Travel:
    """Per id: where it was first reported and the farthest it has been from there."""

    def __init__(self):
        self.first: dict = {}
        self.farthest: dict = {}

    def add(self, est: Estimates) -> None:
        """Take one scan's reported estimates."""
        for lab, m in zip(est.label.tolist(), est.m[:, :2]):
            self.first.setdefault(lab, m.copy())
            self.farthest[lab] = max(self.farthest.get(lab, 0.0),
                                     float(np.linalg.norm(m - self.first[lab])))

    def distinct(self) -> int:
        """Ids reported so far."""
        return len(self.farthest)

    def moved(self, distance: float = MOVED) -> int:
        """Ids that have been farther than ``distance`` (m) from where they were first
        reported."""
        return sum(1 for v in self.farthest.values() if v > distance)


__all__ = ['MOVED', 'Travel']
