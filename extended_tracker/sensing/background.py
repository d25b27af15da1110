"""
Static background of a stationary scanner, learned per beam online.

Notes
-----
Each beam keeps a background range ``b`` (NaN while unknown) and two candidate ranges,
its latest two other than the background, each with the time it has been returned (a
scan period for each return of it). A beam that returned nothing (a dropout, or nothing
in range) or its background ages its first candidate when a neighbouring beam, within
``margin`` across at that range, returned it: a surface at the edge of range, or seen
through a gap now and then, is returned now by one beam, now by another, and each beam
alone took some 50 scans to return it ten times. A return within ``margin`` of ``b`` is
background: it is dropped and refines ``b``. A candidate returned for ``confirm_time``
is *ripe*:

- with no background yet, a ripe candidate becomes it;
- a ripe candidate *farther* than ``b`` (something moved away and revealed what is
  behind) replaces it;
- a candidate *nearer* than ``b`` (something new stands still: a chair moved in) replaces
  it only after ``forget_time``, so people pausing briefly are not learned; but a return
  that none of its neighbours (within ``margin`` across) returned anything near is
  thinner than the beam spacing, no person (a mixed return at an object's edge, a thin
  pole), and replaces it once ripe;
- but a ripe candidate on a beam that has also returned ``b`` within the last
  ``confirm_time``, nearer or farther, becomes the beam's *second* background range: the
  beam flips between the two (an object's edge, a thin post or table leg that the beam
  hits in some scans only). A second range not returned for ``forget_time`` is
  forgotten. (With one candidate every flip restarted it: a post's edge beam never aged.)

Beams whose return lies within ``track_gate`` of a *protecting* track (confirmed,
person-sized and moved ``moved_distance`` beyond its first extent while seen: the caller
decides) are never learned from where the background is known or the beam was seen free,
so a person who walks in and stops stays tracked however long they stand, in front of a
wall or of open space. A track that never moved protects nothing: a static object is
learned like any other (after ``confirm_time`` behind the known background or where it
is unknown, ``forget_time`` in front of it), however it is tracked meanwhile. (Protected
by their own static tracks, furniture revealed behind something learned at start-up on
the MiR recording, a spot on positive_1 and one on the leg_tracker demo were reported
for hundreds of scans.) A return that completes its beam's confirmation is background in
that same scan; ``learned`` marks those beams, so that the caller can drop the tracks
that stood on them.

A beam that has returned nothing for ``confirm_time`` while its background was unknown is
*free* (open space, or nothing within range). Each beam also keeps the farthest range it
returned (open space: infinite): in the warm-up, a return nearer than it by over
``margin`` came into the beam (:func:`arrived`).

A beam of unknown background *continues* a neighbour's surface when it returns that
neighbour's background range (the neighbour within ``margin`` across) and it was never
seen free (hidden behind a walker before its background was learned) or its return lies in
the last ``RANGE_EDGE`` of ``range_max`` (a surface there fades in and out, the beams
between its returns looking free). Such a return is learned at once, and beams continuing
it in turn with it: a wall revealed when the walker leaves is not tracked for the
``confirm_time`` it would take to ripen (the bundled demo's, the ``walls`` scene's, a far
wall on MiR), nor is a wall at the edge of range (5.45 m of 5.6 m on the leg_tracker demo,
once counted as a walker). A person standing in front of the surface by more than
``margin`` continues nothing, nor do returns near a reported track (on leg_tracker
positive_1 a walker standing from start-up, one leg learned in the warm-up, lost the other
leg's returns that way). Where the background is unknown and the beam was never seen free,
tracks protect nothing, so a revealed wall that gets tracked is still learned.

A per-beam model cannot tell a person who stands still from start-up from a piece of
furniture: the caller marks the beams of *objects* (:mod:`sensing.objects`), which are
learned only after ``object_time``.

When the beam count or angles change, what was learned is re-mapped to the new beams by
angle (:meth:`BackgroundState.remapped`).

"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np

from .scan import ScanPoints

RANGE_EDGE = 0.05                   # the last share of range_max: surfaces fade in and out
#: a beam that has returned nothing this long since start-up looks into open space (s);
#: shorter runs of nothing are dropouts (a dark or glancing surface missed now and then)
OPEN_SPACE_TIME = 0.5


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
    background_ago: np.ndarray        # time since a return matched the background
    second: np.ndarray                # second background range (NaN: none)
    second_ago: np.ndarray            # time since a return matched the second range
    candidate2: np.ndarray            # the beam's other recent range (NaN: none)
    candidate2_age: np.ndarray
    object_seen: np.ndarray           # an object returned the first candidate (bool)
    object_seen2: np.ndarray          # an object returned the other candidate (bool)
    farthest: np.ndarray              # farthest range returned (NaN: none yet; inf: open)

    @staticmethod
    def for_scan(scan: ScanPoints) -> 'BackgroundState':
        b = len(scan.angles)
        never = np.full(b, np.inf)
        return BackgroundState(scan.angles.copy(), np.full(b, np.nan), np.full(b, np.nan),
                               np.zeros(b), np.zeros(b), np.zeros(b, dtype=bool),
                               np.zeros(b, dtype=bool), never, np.full(b, np.nan), never,
                               np.full(b, np.nan), np.zeros(b), np.zeros(b, dtype=bool),
                               np.zeros(b, dtype=bool), np.full(b, np.nan))

    def matches(self, scan: ScanPoints) -> bool:
        return (len(self.angles) == len(scan.angles)
                and np.allclose(self.angles, scan.angles, atol=1e-9))

    def remapped(self, scan: ScanPoints) -> 'BackgroundState':
        """
        The state on ``scan``'s beams: each beam takes what was learned on the beam
        nearest its angle, where one lies within half a beam spacing of it; a beam with
        none (past the old field of view) starts unknown. A driver that changes the beam
        count now and then (two beams short, reversed, finer) keeps its background.
        """
        fresh = BackgroundState.for_scan(scan)
        if not len(self.angles) or not len(scan.angles):
            return fresh
        order = np.argsort(self.angles, kind='stable')
        old = self.angles[order]
        step = np.min(np.diff(old)) if len(old) > 1 else np.inf
        at = old.searchsorted(scan.angles)
        upper, lower = np.minimum(at, len(old) - 1), np.maximum(at - 1, 0)
        nearer = np.where(np.abs(scan.angles - old[lower]) <= np.abs(scan.angles - old[upper]),
                          lower, upper)
        hit = np.abs(scan.angles - old[nearer]) <= 0.5 * step + 1e-9
        src = order[nearer[hit]]
        values = {}
        for f in fields(self):
            if f.name in ('angles', 'learned'):
                continue
            mine = getattr(fresh, f.name).copy()
            mine[hit] = getattr(self, f.name)[src]
            values[f.name] = mine
        return replace(fresh, **values)


def beams_near_tracks(scan: ScanPoints, track_centres: np.ndarray,
                      track_radius: np.ndarray, gate: float, guard: np.ndarray):
    """
    ``(protected, near)``: the beams whose return lies within ``radius + gate`` of a
    ``guard`` track's centre (``guard``: bool over the tracks; the protecting ones), and
    of any track's, from one pass over the returns.
    """
    near = np.zeros(len(scan.angles), dtype=bool)
    prot = np.zeros(len(scan.angles), dtype=bool)
    if not len(track_centres) or not len(scan.points):
        return prot, near
    p = scan.points
    dx = p[:, 0, None] - track_centres[None, :, 0]
    dy = p[:, 1, None] - track_centres[None, :, 1]
    within = np.sqrt(dx * dx + dy * dy) <= (track_radius + gate)[None, :]   # norm's bits
    near[scan.beam[np.any(within, axis=1)]] = True
    if guard.any():
        prot[scan.beam[np.any(within[:, guard], axis=1)]] = True
    return prot, near


NEIGHBOUR_BEAMS = 8                 # at most this many beams either side (a near surface)
_OFFSETS = np.arange(-NEIGHBOUR_BEAMS, NEIGHBOUR_BEAMS + 1)
_NOT_SELF = _OFFSETS != 0
with np.errstate(divide='ignore'):
    _PER_OFFSET = 1.0 / np.abs(_OFFSETS)           # inf for the beam itself


def _padded(a, fill, wrap=False):
    """``a`` with NEIGHBOUR_BEAMS ``fill`` values either side, so that the window
    ``i + NEIGHBOUR_BEAMS + _OFFSETS`` of any beam ``i`` is inside it; with ``wrap`` (a
    full turn of beams, the last next to the first) the other end's values instead."""
    if wrap and len(a) >= NEIGHBOUR_BEAMS:
        return np.concatenate([a[-NEIGHBOUR_BEAMS:], a, a[:NEIGHBOUR_BEAMS]])
    pad = np.full(NEIGHBOUR_BEAMS, fill, dtype=a.dtype)
    return np.concatenate([pad, a, pad])


def reach_of(angle_step, margin):
    """Per offset: the range up to which that many beams ``angle_step`` apart are within
    ``margin`` across (0 for all of them in a scan of one beam, step 0: no neighbours)."""
    if angle_step <= 0:
        return np.zeros(len(_OFFSETS))
    return _PER_OFFSET * (margin / angle_step)


def _neighbour_returned(c, r, learn, idle, reach, margin, wrap=False):
    """
    The ``idle`` beams (bool) whose candidate range ``c`` a neighbouring beam returned this
    scan (a ``learn`` return within ``margin`` of it); a beam's neighbours are the beams
    within ``margin`` across at its candidate's range (``reach``, :func:`reach_of`), at
    most :data:`NEIGHBOUR_BEAMS` either side.
    """
    hit = np.zeros(len(c), dtype=bool)
    src = learn.nonzero()[0]
    if not len(src):
        return hit
    j = src[:, None] + _OFFSETS                        # each return's neighbour beams
    cj = _padded(c, np.nan, wrap)[j + NEIGHBOUR_BEAMS]  # NaN (none, or off the scan): False
    ok = (_padded(idle, False, wrap)[j + NEIGHBOUR_BEAMS]
          & (np.abs(r[src, None] - cj) <= margin) & (cj <= reach))
    hit[j[ok] % len(c) if wrap else j[ok]] = True
    return hit


def _alone(r, which, reach, margin, wrap=False):
    """
    Which of the returns of beams ``which`` (indices) are thinner than the beam spacing:
    they have neighbours within ``margin`` across, none of which returned anything within
    ``margin`` of them (a mixed return at an edge, a thin pole; no person).
    """
    rs = r[which, None]
    rj = _padded(r, np.inf, wrap)[which[:, None] + _OFFSETS + NEIGHBOUR_BEAMS]
    near = (np.abs(rj - rs) <= margin) & _NOT_SELF & (rs <= reach)
    return (rs[:, 0] <= reach[NEIGHBOUR_BEAMS + 1]) & ~np.any(near, axis=1)


def continues_surface(r, b, which, reach, margin, wrap=False):
    """
    Which of the ``which`` beams (bool) return a range within ``margin`` of a neighbouring
    beam's background ``b`` (NaN: none), the neighbours within ``margin`` across at that
    range (``reach``, :func:`reach_of`); a beam so found serves as a neighbour in turn, so a
    stretch of such beams is found from its end next to the known background.

    Notes
    -----
    Found one ring of neighbours at a time, a stretch took a round for every few beams (a
    thousand-beam stretch 23 ms). Adjacent ``which`` beams within ``margin`` of each other,
    each within reach of the other, find each other whichever is found first, so such runs
    are taken whole: a round per gap in a stretch (0.9 ms for that one).
    """
    b = b.copy()
    todo = which.copy()
    out = np.zeros(len(r), dtype=bool)
    run = None
    while True:
        idx = todo.nonzero()[0]
        if not len(idx):
            return out
        rs = r[idx, None]
        bj = _padded(b, np.nan, wrap)[idx[:, None] + _OFFSETS + NEIGHBOUR_BEAMS]
        hit = np.any((np.abs(bj - rs) <= margin) & (rs <= reach), axis=1)
        if not hit.any():
            return out
        if run is None:
            run = _runs(r, which, reach[NEIGHBOUR_BEAMS + 1], margin, wrap)
        new = todo & np.isin(run, run[idx[hit]])
        out |= new
        b[new] = r[new]
        todo &= ~new


def _runs(r, which, reach_one, margin, wrap=False):
    """A run label per beam: adjacent ``which`` beams within ``margin`` of each other, each
    within ``reach_one`` (one beam apart within ``margin`` across), share one."""
    n = len(r)
    link = which & np.roll(which, -1)                  # beam i and the next
    i = link.nonzero()[0]
    ri, rn = r[i], r[(i + 1) % n]
    link[i] = (np.abs(ri - rn) <= margin) & (np.maximum(ri, rn) <= reach_one)
    run = np.cumsum(np.concatenate([[True], ~link[:-1]])) - 1   # link[-1]: the seam's
    if wrap and link[-1]:
        run[run == run[-1]] = run[0]                   # the run across the seam
    return run


def update_background(state: BackgroundState | None, scan: ScanPoints, dt: float, cfg,
                      protected: np.ndarray, tracked: np.ndarray | None = None,
                      objects: np.ndarray | None = None) -> tuple[BackgroundState, np.ndarray]:
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
        Beams near protecting tracks (confirmed, person-sized, moved): not learned from
        where the background is known or the beam was seen free.
    tracked : (B,) bool array, optional
        Beams near any reported track: their returns do not continue a neighbour's
        background at once (a person standing from start-up whose legs were learned in
        part would lose the rest); they ripen as any return does.

    """
    if state is None:
        state = BackgroundState.for_scan(scan)
    elif not state.matches(scan):
        state = state.remapped(scan)
    r = scan.ranges                                   # inf where no return
    with np.errstate(invalid='ignore'):
        seen = _refine_known(state, r, dt, cfg)
        learn = seen.returned & ~seen.is_bg & ~(protected & (seen.known | seen.free))
        c, c2, age, age2, was_object, was_object2 = _candidates(state, scan, dt, cfg, learn,
                                                                 seen)
        if objects is not None:
            was_object |= objects & learn
        promote, second = _promotions(scan, cfg, learn, seen, c, age, tracked, was_object)
        b = np.where(promote, c, seen.b)
        b_ago = np.where(promote, 0.0, seen.b_ago)
        s2 = np.where(second, c, np.where(seen.s2_ago > cfg.forget_time, np.nan, seen.s2))
        s2_ago = np.where(second, 0.0, seen.s2_ago)
        learned = promote | second
        age = np.where(learned, 0.0, age)
        farthest = _farthest(state.farthest, r, seen)
    keep = ~(seen.is_bg | learned)[scan.beam]
    return BackgroundState(state.angles, b, c, age, seen.empty, seen.free, learned, b_ago, s2,
                           s2_ago, c2, age2, was_object & ~learned, was_object2, farthest), keep


def _farthest(farthest, r, seen: _Seen):
    """Each beam's farthest return so far: NaN until it returns something, infinite once
    it has returned nothing for ``OPEN_SPACE_TIME`` since start-up (open space; less is a
    dropout, a surface missed a scan or two, whose next return is not new)."""
    opened = np.isnan(farthest) & (seen.empty >= OPEN_SPACE_TIME - 1e-6)
    return np.where(seen.returned, np.fmax(farthest, r), np.where(opened, np.inf, farthest))


def arrived(state: BackgroundState | None, scan: ScanPoints, margin: float) -> np.ndarray:
    """
    Over ``scan``'s beams: the return is nearer by more than ``margin`` than anything its
    beam returned before, or than open space (:func:`_farthest`): something came into the
    beam. A wall revealed is farther, never nearer.
    """
    if state is None or not state.matches(scan):
        return np.zeros(len(scan.angles), dtype=bool)
    with np.errstate(invalid='ignore'):
        return scan.ranges < state.farthest - margin


@dataclass(frozen=True)
class _Seen:
    """What one scan says of the known ranges, beam by beam (see :func:`_refine_known`)."""

    b: np.ndarray
    s2: np.ndarray
    b_ago: np.ndarray
    s2_ago: np.ndarray
    known: np.ndarray
    returned: np.ndarray
    is_bg: np.ndarray
    empty: np.ndarray
    free: np.ndarray
    gain: float


def _refine_known(state: BackgroundState, r: np.ndarray, dt: float, cfg) -> _Seen:
    """
    Match the returns ``r`` with the background and second ranges, refine those seen
    (exponential smoothing with time constant ``learn_time``), and age the beams that
    return nothing: a beam of unknown background that returned nothing for
    ``confirm_time`` in a row is free, and a later return does not undo it (a person
    standing there).
    """
    b, s2, margin = state.background, state.second, cfg.margin
    known = np.isfinite(b)
    seen = np.isfinite(r)
    on_b = known & seen & (np.abs(r - b) <= margin)
    on_s2 = seen & ~on_b & (np.abs(r - s2) <= margin)         # NaN: never
    gain = min(1.0, dt / cfg.learn_time)
    empty = np.where(seen | known, 0.0, state.empty_age + dt)
    return _Seen(b=np.where(on_b, b + gain * (r - b), b),
                 s2=np.where(on_s2, s2 + gain * (r - s2), s2),
                 b_ago=np.where(on_b, 0.0, state.background_ago + dt),
                 s2_ago=np.where(on_s2, 0.0, state.second_ago + dt),
                 known=known, returned=seen, is_bg=on_b | on_s2, empty=empty,
                 free=state.free | (empty >= cfg.confirm_time - 1e-6), gain=gain)


def _candidates(state: BackgroundState, scan: ScanPoints, dt: float, cfg, learn, seen: _Seen):
    """
    The beam's two latest ranges, each ageing by a scan period whenever it is returned
    (or a neighbour returns it); the one returned this scan is put first, a new range
    pushes the first to second place. Each keeps whether an object returned it. Returns
    ``(c, c2, age, age2, object_seen, object_seen2)``.
    """
    r, margin = scan.ranges, cfg.margin
    c, age = state.candidate, state.candidate_age
    c2, age2 = state.candidate2, state.candidate2_age
    ob, ob2 = state.object_seen, state.object_seen2
    on_c = np.abs(r - c) <= margin
    on_c2 = learn & ~on_c & (np.abs(r - c2) <= margin)
    c, c2 = np.where(on_c2, c2, c), np.where(on_c2, c, c2)
    age, age2 = np.where(on_c2, age2, age), np.where(on_c2, age, age2)
    ob, ob2 = np.where(on_c2, ob2, ob), np.where(on_c2, ob, ob2)
    same = learn & (on_c | on_c2)
    fresh = learn & ~same
    c2, age2 = np.where(fresh, c, c2), np.where(fresh, age, age2)
    ob, ob2 = ob & ~fresh, np.where(fresh, ob, ob2)
    # ages count scans' dt with a little slack so that k scans of dt reach k * dt
    age = np.where(same, age + dt, np.where(fresh, 0.0, age))
    c = np.where(same, c + seen.gain * (r - c), np.where(fresh, r, c))
    # a beam that returned nothing or its background ages its candidate when a
    # neighbour returned that range: a surface at the edge of range, or behind a gap,
    # sparkles over the beams
    reach = reach_of(scan.angle_step, margin)
    idle = ~seen.returned | seen.is_bg
    age = np.where(_neighbour_returned(c, r, learn, idle, reach, margin, scan.full_turn),
                   age + dt, age)
    return c, c2, age, age2, ob, ob2


def _promotions(scan: ScanPoints, cfg, learn, seen: _Seen, c, age, tracked, objects=None):
    """
    Which candidates become the background, and which the second range.

    Farther than the background: once ripe (``confirm_time``). Nearer: after
    ``forget_time``, or once ripe for a return thinner than the beam spacing (no person;
    a mixed return at an edge, a thin pole). A background returned within
    ``confirm_time`` means the beam flips between it and the candidate (an object's edge,
    a thin post): the candidate is a second range. A beam of unknown background, never
    seen free or returning from the edge of range, that returns the range of a
    neighbour's background continues that surface and is learned at once (not near a
    track). An object's beam (``objects``) is promoted once returned for ``object_time``.
    """
    r, b, margin = scan.ranges, seen.b, cfg.margin
    reach = reach_of(scan.angle_step, margin)
    wrap = scan.full_turn                             # the first beam next to the last
    farther = ~seen.known | (c > b + margin)
    nearer = seen.known & (c < b - margin)
    ripe = age >= cfg.confirm_time - 1e-6
    lately = seen.known & (seen.b_ago <= cfg.confirm_time)
    long = age >= cfg.forget_time - 1e-6
    thin = learn & nearer & ripe & ~lately & ~long
    if thin.any():
        which = thin.nonzero()[0]
        thin[which] = _alone(r, which, reach, margin, wrap)
    at_edge = r >= (1.0 - RANGE_EDGE) * scan.range_max   # inf (no return): learn drops it
    hidden = learn & ~seen.known & (~seen.free | at_edge)
    if tracked is not None:
        hidden &= ~tracked
    if hidden.any():
        hidden = continues_surface(r, b, hidden, reach, margin, wrap)
    promote = learn & ((farther & ripe & ~lately) | (nearer & (long | thin))) | hidden
    second = learn & ripe & lately & ~promote
    if objects is not None and objects.any():
        due = age >= cfg.object_time - 1e-6 if cfg.object_time > 0 else np.zeros_like(learn)
        promote = np.where(objects, learn & due, promote)
        second &= ~objects
    return promote, second
