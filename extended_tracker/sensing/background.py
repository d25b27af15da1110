"""
Static background of a stationary scanner, learned per beam online.

Notes
-----
Each beam keeps a background range ``b`` (NaN while unknown) and a candidate range ``c``
with the time it has persisted. A return within ``margin`` of ``b`` is background: it is
dropped and refines ``b``. Otherwise the candidate ages while the beam keeps returning
the same range:

- with no background yet, a candidate that persists ``confirm_time`` becomes it;
- a candidate *farther* than ``b`` (something moved away and revealed what is behind)
  replaces it after ``confirm_time``;
- a beam with no return (a dropout, or nothing in range) changes nothing;
- a candidate *nearer* than ``b`` (something new stands still: a chair moved in) replaces
  it only after ``forget_time``, so people pausing briefly are not learned.

Beams whose return lies within ``track_gate`` of a *protecting* track (confirmed and
person-sized: the caller decides) and in front of a known background are never dropped and
never learned from, so a person who walks in and stops stays tracked however long they
stand. A return *behind* the known background is held only by a track that has moved
``moved_distance`` while seen (a person): a track on a static object cannot keep the
background behind it from being learned (on the MiR recording something 0.85 m from the
scanner at start-up was learned, then left, and the furniture it had hidden was tracked
and kept itself from being learned for the whole run). A return that completes
its beam's confirmation is background in that same scan; ``learned`` marks those beams,
so that the caller can drop the tracks that stood on them.

A beam that has returned nothing for ``confirm_time`` while its background was
unknown is *free* (open space, or nothing within range). A free beam is protected only by
a track that has also moved ``moved_distance`` while seen (``protected_free``): a person
who stops in open space stays tracked, while something that flickers at the edge of range
and gets tracked where it stands is still learned. Where the background is unknown and the
beam was never seen free (a stretch of wall hidden behind a person since start-up), tracks
protect nothing, so a revealed wall that gets tracked is still learned.

Limitation: a per-beam model cannot tell a person who stands still from start-up from a
piece of furniture; such a person becomes background after ``confirm_time``. Disable the
background where people stand still from the start and there is no static clutter.
The model resets when the beam count or angles change.

"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scan import ScanPoints


@dataclass(frozen=True)
class BackgroundState:
    """Per-beam arrays of length B (message order)."""

    angles: np.ndarray
    background: np.ndarray
    candidate: np.ndarray
    candidate_age: np.ndarray
    empty_age: np.ndarray             # time a beam of unknown background returned nothing
    free: np.ndarray                  # seen empty for confirm_time (bool)
    learned: np.ndarray               # became background in the last update (bool)

    @staticmethod
    def for_scan(scan: ScanPoints) -> 'BackgroundState':
        b = len(scan.angles)
        return BackgroundState(scan.angles.copy(), np.full(b, np.nan), np.full(b, np.nan),
                               np.zeros(b), np.zeros(b), np.zeros(b, dtype=bool),
                               np.zeros(b, dtype=bool))

    def matches(self, scan: ScanPoints) -> bool:
        return (len(self.angles) == len(scan.angles)
                and np.allclose(self.angles, scan.angles, atol=1e-9))


def protected_beams(scan: ScanPoints, track_centres: np.ndarray, track_radius: np.ndarray,
                    gate: float, moved: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Beams whose return lies within ``radius + gate`` of a confirmed track centre, and those
    near a track flagged in ``moved`` (for free beams).
    """
    prot = np.zeros(len(scan.angles), dtype=bool)
    prot_moved = prot.copy()
    if not len(track_centres) or not len(scan.points):
        return prot, prot_moved
    d = np.linalg.norm(scan.points[:, None, :] - track_centres[None, :, :], axis=2)
    close = d <= (track_radius + gate)[None, :]
    prot[scan.beam[np.logical_or.reduce(close, axis=1)]] = True
    prot_moved[scan.beam[np.logical_or.reduce(close[:, moved], axis=1)]] = True
    return prot, prot_moved


def update_background(state: BackgroundState | None, scan: ScanPoints, dt: float, cfg,
                      protected: np.ndarray, protected_free: np.ndarray | None = None
                      ) -> tuple[BackgroundState, np.ndarray]:
    """
    Learn from one scan and return the new state and a keep-mask over ``scan.points``.

    Parameters
    ----------
    state : BackgroundState or None
    scan : ScanPoints
    dt : float
        Time since the previous scan (s), ``>= 0``.
    cfg : BackgroundConfig
    protected : (B,) bool array
        Beams near confirmed tracks: kept and not learned from where the return lies in
        front of a known background.
    protected_free : (B,) bool array, optional
        Beams near confirmed tracks that moved: kept and not learned from where the beam
        was seen free, or where its return lies behind a known background (default: none).

    """
    if state is None or not state.matches(scan):
        state = BackgroundState.for_scan(scan)
    b = state.background.copy()
    c = state.candidate.copy()
    age = state.candidate_age.copy()
    r = scan.ranges                                   # inf where no return
    margin = cfg.margin
    known = np.isfinite(b)
    with np.errstate(invalid='ignore'):
        is_bg = known & np.isfinite(r) & (np.abs(r - b) <= margin)
        # refine the background where it is seen (exponential smoothing, time constant)
        gain = min(1.0, dt / cfg.learn_time)
        b = np.where(is_bg, b + gain * (r - b), b)
        # candidates: a beam returning the same range as before keeps ageing; a beam with
        # no return (dropout, or nothing in range) tells nothing and changes nothing
        seen = np.isfinite(r)
        # free: a beam of unknown background that returned nothing for confirm_time in a
        # row; a later return does not undo it (a person standing there)
        empty = np.where(seen | known, 0.0, state.empty_age + dt)
        free = state.free | (empty >= cfg.confirm_time - 1e-6)
        same = seen & np.isfinite(c) & (np.abs(r - c) <= margin)
        if protected_free is None:
            protected_free = np.zeros_like(protected)
        # protecting tracks hold returns in front of the background; behind it, only
        # tracks that moved (a return there is what an object that moved away revealed)
        held = protected & known & ((r < b) | protected_free)
        learn = seen & ~is_bg & ~held & ~(protected_free & free & ~known)
        # ages count scans' dt with a little slack so that k scans of dt reach k * dt
        age = np.where(learn, np.where(same, age + dt, 0.0), age)
        c = np.where(learn, np.where(same, c + gain * (r - c), r), c)
        farther = ~known | (c > b + margin)
        nearer = known & (c < b - margin)
        ripe = age >= cfg.confirm_time - 1e-6
        promote = learn & ((farther & ripe) | (nearer & (age >= cfg.forget_time - 1e-6)))
        b = np.where(promote, c, b)
        age = np.where(promote, 0.0, age)
    keep = ~(is_bg | promote)[scan.beam]
    return BackgroundState(state.angles, b, c, age, empty, free, promote), keep
