"""
Ray-casting simulator of a planar laser scanner, standing still or carried along a path.

Objects are ellipses or rectangles moving with constant velocity or a coordinated turn,
optionally standing still for a while; static walls are line segments. Every beam is
cast against every shape and returns the nearest hit with Gaussian range noise; beams
drop out at random; clutter returns land on random beams in front of what they would
hit. Ground truth (centre, velocity, extent matrix with the ellipse's second moments)
comes with every scan.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from . import legs
from ..frames.pose import Pose2
from ..sensing.scan import Header, ScanData, Stamp


@dataclass(frozen=True)
class SimObject:
    """
    A moving shape.

    Parameters
    ----------
    start : (x, y) m at ``t_start``; velocity : (vx, vy) m/s
    shape : 'ellipse' (semi-axes ``a``, ``b``), 'rectangle' (length ``a``, width ``b``)
        or 'legs' (a walker at leg height, :mod:`sim.legs`; ``a``, ``b`` unused)
    turn_rate : rad/s (coordinated turn; 0 for constant velocity)
    stops : tuple of (t0, t1) during which the object stands still
    kind : label only ('pedestrian', 'bicycle', 'car', 'standing')
    gait_phase : rad, of the legs' swing ('legs' only)

    """

    start: tuple
    velocity: tuple = (0.0, 0.0)
    shape: str = 'ellipse'
    a: float = 0.25
    b: float = 0.2
    turn_rate: float = 0.0
    t_start: float = 0.0
    t_end: float = math.inf
    stops: tuple = ()
    kind: str = 'pedestrian'
    gait_phase: float = 0.0

    def state(self, t: float):
        """Centre, velocity and heading at time ``t`` (integrating the stops exactly)."""
        moving = t - self.t_start
        for t0, t1 in self.stops:
            moving -= max(0.0, min(t, t1) - t0) if t > t0 else 0.0
        moving = max(moving, 0.0)
        v = np.asarray(self.velocity, float)
        speed = float(np.hypot(*v))
        h0 = math.atan2(v[1], v[0]) if speed > 0 else 0.0
        if abs(self.turn_rate) < 1e-9:
            c = np.asarray(self.start, float) + v * moving
            h = h0
        else:
            w = self.turn_rate
            h = h0 + w * moving
            c = np.asarray(self.start, float) + speed / w * np.array(
                [math.sin(h) - math.sin(h0), -math.cos(h) + math.cos(h0)])
        standing = any(t0 <= t < t1 for t0, t1 in self.stops)
        vel = np.zeros(2) if standing else speed * np.array([math.cos(h), math.sin(h)])
        return c, vel, h

    def alive(self, t: float) -> bool:
        return self.t_start <= t <= self.t_end

    @property
    def radius(self) -> float:
        """Radius (m) of the smallest circle about the centre that holds the shape."""
        if self.shape == 'rectangle':
            return 0.5 * math.hypot(self.a, self.b)
        if self.shape == 'legs':
            return legs.REACH
        return max(self.a, self.b)

    def centres(self, times: np.ndarray) -> np.ndarray:
        """Centres (len(times), 2) at ``times`` (s); NaN where the object is not alive."""
        return np.array([self.state(t)[0] if self.alive(t) else (np.nan, np.nan)
                         for t in times]).reshape(-1, 2)

    def extent(self, heading: float) -> np.ndarray:
        """Extent matrix with the shape's second moments (rectangle: a = L / sqrt(3))."""
        if self.shape == 'rectangle':
            ax, bx = self.a / math.sqrt(3.0), self.b / math.sqrt(3.0)
        else:
            ax, bx = self.a, self.b
        c, s = math.cos(heading), math.sin(heading)
        Rm = np.array([[c, -s], [s, c]])
        return Rm @ np.diag([ax * ax, bx * bx]) @ Rm.T


@dataclass(frozen=True)
class LaserSpec:
    """A planar scanner at the origin looking along +x."""

    angle_min: float = -math.pi / 2
    angle_max: float = math.pi / 2
    n_beams: int = 361
    range_min: float = 0.05
    range_max: float = 13.0
    noise_std: float = 0.01
    dropout: float = 0.01
    clutter_per_scan: float = 0.0
    no_return: float = math.inf           # what a beam without a hit reports
    rate_hz: float = 10.0
    frame_id: str = 'laser'
    phase: float = 0.0                    # s: the first scan's time (scanners out of step)

    @property
    def increment(self) -> float:
        return (self.angle_max - self.angle_min) / (self.n_beams - 1)

    def angles(self) -> np.ndarray:
        return self.angle_min + self.increment * np.arange(self.n_beams)


@dataclass(frozen=True)
class Drive:
    """
    A robot's path in the fixed frame: keyframes ``(t, x, y, yaw)`` of its base,
    interpolated linearly between them (yaw the shorter way round), held after the last;
    and the scanner's ``mount`` on the base.
    """

    keys: tuple
    mount: Pose2 = Pose2()
    base_frame: str = 'base_link'
    fixed_frame: str = 'odom'

    def base_pose(self, t: float) -> Pose2:
        k = np.asarray(self.keys, float)
        i = int(np.clip(np.searchsorted(k[:, 0], t) - 1, 0, len(k) - 2)) if len(k) > 1 else 0
        if len(k) == 1 or t >= k[-1, 0]:
            return Pose2(*k[-1 if t >= k[-1, 0] else 0, 1:])
        s = min(max((t - k[i, 0]) / (k[i + 1, 0] - k[i, 0]), 0.0), 1.0)
        turn = math.remainder(k[i + 1, 3] - k[i, 3], 2 * math.pi)
        x, y = k[i, 1:3] + s * (k[i + 1, 1:3] - k[i, 1:3])
        return Pose2(float(x), float(y), float(k[i, 3] + s * turn))

    def pose(self, t: float) -> Pose2:
        """The scanner's pose in the fixed frame at ``t``."""
        return self.base_pose(t).compose(self.mount)


@dataclass(frozen=True)
class Scene:
    """Objects, walls (segments ((x0, y0), (x1, y1))) and the scanner (carried along
    ``drive`` when given, else at the origin of the frame the walls are in)."""

    objects: tuple
    walls: tuple = ()
    laser: LaserSpec = field(default_factory=LaserSpec)
    drive: Drive | None = None

    def pose(self, t: float) -> Pose2 | None:
        return None if self.drive is None else self.drive.pose(t)


@dataclass(frozen=True)
class TruthObject:
    """Ground truth of one object in one scan."""

    id: int
    centre: np.ndarray
    velocity: np.ndarray
    extent: np.ndarray
    kind: str
    visible_beams: int


GAP_STEP = 0.02    # s between the times the gap is checked at (< 0.06 m at 3 m/s)


def bounding_gap(a: SimObject, b: SimObject, seconds: float) -> float:
    """
    The least gap (m) between the bounding circles of ``a`` and ``b`` while both are
    alive in the first ``seconds`` (inf if they never are); below 0 the shapes may overlap.

    Sampled every ``GAP_STEP``; objects that walk through one another are beyond
    what a laser can separate, and no two people or vehicles do it.
    """
    times = _gap_times(seconds)
    return _gap(a.centres(times), a.radius, b.centres(times), b.radius)


def _gap_times(seconds: float) -> np.ndarray:
    return np.arange(0.0, seconds + GAP_STEP / 2, GAP_STEP)


def _gap(ca, ra, cb, rb) -> float:
    gap = np.linalg.norm(ca - cb, axis=1) - (ra + rb)
    return float(np.nanmin(gap)) if np.isfinite(gap).any() else math.inf


def _ray_ellipse(d, c, X):
    """Distance along unit rays ``d`` (B, 2) to the ellipse (c, X) or inf."""
    Xi = np.linalg.inv(X)
    # |t d - c|_Xi = 1  ->  (d'Xi d) t^2 - 2 (d'Xi c) t + c'Xi c - 1 = 0
    A = np.einsum('bi,ij,bj->b', d, Xi, d)
    B = -2 * d @ (Xi @ c)
    C = c @ Xi @ c - 1.0
    disc = B * B - 4 * A * C
    with np.errstate(invalid='ignore'):
        root = np.sqrt(disc)
        t1 = (-B - root) / (2 * A)
        t2 = (-B + root) / (2 * A)
    t = np.where(t1 > 0, t1, np.where(t2 > 0, t2, np.inf))
    return np.where(disc >= 0, t, np.inf)


def _ray_segments(d, p0, p1):
    """Distance along unit rays ``d`` (B, 2) to segments p0-p1 (S, 2): (B,) nearest or inf."""
    if not len(p0):
        return np.full(len(d), np.inf)
    e = p1 - p0                                           # (S, 2)
    # t d = p0 + s e  ->  solve [d, -e] [t, s]^T = p0
    den = d[:, None, 0] * (-e[None, :, 1]) - d[:, None, 1] * (-e[None, :, 0])
    with np.errstate(divide='ignore', invalid='ignore'):
        t = (p0[None, :, 0] * (-e[None, :, 1]) - p0[None, :, 1] * (-e[None, :, 0])) / den
        s = (d[:, None, 0] * p0[None, :, 1] - d[:, None, 1] * p0[None, :, 0]) / den
    ok = (np.abs(den) > 1e-12) & (t > 0) & (s >= 0) & (s <= 1)
    return np.where(ok, t, np.inf).min(axis=1)


def _rectangle_segments(c, heading, length, width):
    ch, sh = math.cos(heading), math.sin(heading)
    u = np.array([ch, sh]) * length / 2
    v = np.array([-sh, ch]) * width / 2
    corners = np.array([c + u + v, c - u + v, c - u - v, c + u - v])
    return corners, np.roll(corners, -1, axis=0)


def simulate(scene: Scene, duration: float, seed: int, t0_ns: int = 1_700_000_000_000_000_000):
    """
    Scans and truth for ``duration`` seconds at the scanner's rate.

    Returns
    -------
    list of (ScanData, list[TruthObject])

    """
    return list(simulated_scans(scene, duration, seed, t0_ns))


def simulated_scans(scene: Scene, duration: float, seed: int,
                    t0_ns: int = 1_700_000_000_000_000_000):
    """:func:`simulate` one scan at a time (a long run need not fit in memory)."""
    rng = np.random.default_rng(seed)
    L = scene.laser
    angles = L.angles()
    d = np.column_stack([np.cos(angles), np.sin(angles)])
    walls = np.asarray(scene.walls, float).reshape(-1, 2, 2)
    wall_range = _ray_segments(d, walls[:, 0], walls[:, 1])
    n_scans = int(round(duration * L.rate_hz))
    for k in range(n_scans):
        t = k / L.rate_hz + L.phase
        pose = scene.pose(t) or Pose2()
        if pose.is_identity:
            r = wall_range.copy()
        else:                                   # the world as the scanner sees it
            local = pose.to_inner(walls.reshape(-1, 2)).reshape(-1, 2, 2)
            r = _ray_segments(d, local[:, 0], local[:, 1])
        owner = np.full(L.n_beams, -1)
        truth = []
        for i, ob in enumerate(scene.objects):
            if not ob.alive(t):
                continue
            c, vel, h = ob.state(t)
            c_in, h_in = pose.to_inner(c[None, :])[0], h - pose.yaw
            X = ob.extent(h)
            if ob.shape == 'rectangle':
                p0, p1 = _rectangle_segments(c_in, h_in, ob.a, ob.b)
                hit = _ray_segments(d, p0, p1)
            elif ob.shape == 'legs':
                gait = (h_in, float(np.hypot(*vel)), t, ob.gait_phase)
                hit = np.minimum(*(_ray_ellipse(d, p, legs.LEG_EXTENT)
                                   for p in legs.leg_centres(c_in, *gait)))
                X = legs.legs_extent(h, *gait[1:])
            else:
                hit = _ray_ellipse(d, c_in, ob.extent(h_in))
            nearer = hit < r
            r = np.where(nearer, hit, r)
            owner = np.where(nearer, i, owner)
            truth.append([i, c, vel, X, ob.kind])
        # beams the object returns: the nearest hit, within the scanner's range
        counts = np.bincount(owner[(owner >= 0) & (r <= L.range_max)],
                             minlength=len(scene.objects))
        truth = [TruthObject(i, c, v, X, kind, int(counts[i])) for i, c, v, X, kind in truth]
        ranges = r + rng.normal(0.0, L.noise_std, L.n_beams)    # no hit: inf + noise = inf
        drop = rng.random(L.n_beams) < L.dropout
        ranges = np.where(drop, np.inf, ranges)
        n_clutter = rng.poisson(L.clutter_per_scan) if L.clutter_per_scan > 0 else 0
        if n_clutter:
            beams = rng.choice(L.n_beams, size=min(n_clutter, L.n_beams), replace=False)
            limit = np.minimum(ranges[beams], L.range_max)
            ranges[beams] = rng.uniform(L.range_min, limit)
        ranges = np.where((ranges > L.range_max) | ~np.isfinite(ranges), L.no_return, ranges)
        stamp = t0_ns + int(round(t * 1e9))
        scan = ScanData(
            header=Header(Stamp(stamp // 1_000_000_000, stamp % 1_000_000_000), L.frame_id),
            angle_min=L.angle_min, angle_max=L.angle_max, angle_increment=L.increment,
            range_min=L.range_min, range_max=L.range_max,
            ranges=ranges.astype(np.float32), scan_time=1.0 / L.rate_hz)
        yield scan, truth


# --- the scenario suite (fixed seeds live with the callers) ---

def tutorial_scene(occluder_range: float = 2.5) -> Scene:
    """
    The tutorial's setting: 180 deg, 0.5 deg, 13 m; four pedestrians. One stands still;
    one walks behind it (fully hidden for about 1.8 s), one later walks in front of it
    (hiding the stander), and one walks elsewhere.
    """
    return Scene(objects=(
        SimObject((occluder_range, 0.0), (0.0, 0.0), kind='standing'),
        SimObject((6.0, -3.0), (0.0, 0.6)),                        # behind the stander
        SimObject((1.5, 3.5), (0.0, -0.7), t_start=3.0),           # in front of it
        SimObject((9.0, 4.0), (-0.5, -0.3)),
    ), laser=LaserSpec())


def occlusion_scene() -> Scene:
    """
    One pedestrian standing at 2.5 m (shoulders across the line of sight), another walking
    behind it at 6 m and 0.5 m/s: fully hidden for about 1.9 s.
    """
    return Scene(objects=(
        SimObject((2.5, 0.0), (0.0, 0.0), a=0.2, b=0.3, kind='standing'),
        SimObject((6.0, -3.0), (0.0, 0.5)),
    ), laser=LaserSpec())


def mixed_traffic_scene() -> Scene:
    """A car, a bicycle and pedestrians in a 270 deg / 0.25 deg / 30 m scan."""
    laser = LaserSpec(angle_min=-3 * math.pi / 4, angle_max=3 * math.pi / 4, n_beams=1081,
                      range_max=30.0, clutter_per_scan=3.0)
    return Scene(objects=(
        SimObject((-12.0, 8.0), (5.0, 0.0), shape='rectangle', a=4.5, b=1.8, kind='car'),
        SimObject((10.0, -6.0), (-3.5, 0.5), shape='ellipse', a=0.9, b=0.3, kind='bicycle'),
        SimObject((5.5, 10.0), (-2.0, -3.0), shape='ellipse', a=0.9, b=0.3, kind='bicycle'),
        SimObject((3.0, 2.0), (0.6, 0.8)),
        SimObject((6.0, -2.0), (-0.5, 0.9)),
        SimObject((-4.0, -3.0), (0.9, 0.2)),
        SimObject((8.0, 4.0), (-0.8, -0.5), turn_rate=0.3),
        SimObject((-6.0, 4.0), (0.7, -0.7)),
        SimObject((2.0, -5.5), (0.2, 1.0)),
        SimObject((12.0, 0.0), (-1.0, 0.1)),
    ), laser=laser)


def walls_scene() -> Scene:
    """A room: walls, a table and a cabinet; one person walks in and stops for 10 s."""
    walls = (
        ((-2.0, -5.0), (10.0, -5.0)), ((10.0, -5.0), (10.0, 5.0)), ((10.0, 5.0), (-2.0, 5.0)),
        ((4.0, 2.5), (5.5, 2.5)), ((5.5, 2.5), (5.5, 3.3)), ((5.5, 3.3), (4.0, 3.3)),
        ((4.0, 3.3), (4.0, 2.5)),                                  # a table
        ((7.0, -4.9), (8.5, -4.9)), ((8.5, -4.9), (8.5, -4.3)), ((8.5, -4.3), (7.0, -4.3)),
        ((7.0, -4.3), (7.0, -4.9)),                                # a cabinet
    )
    person = SimObject((8.0, -3.5), (-0.8, 0.6), t_start=1.0, stops=((4.0, 14.0),))
    return Scene(objects=(person,), walls=walls, laser=LaserSpec())


def demo_scene() -> Scene:
    """
    The bundled demo: a room with a table and a cabinet. A walks in and stands for 5 s;
    B walks behind A while A stands (hidden ~1.5 s); C crosses the room diagonally.
    """
    room = walls_scene().walls
    return Scene(objects=(
        SimObject((8.5, -3.8), (-1.0, 0.8), t_start=0.5, stops=((3.0, 8.0),), kind='A'),
        SimObject((8.0, -4.0), (0.0, 0.55), t_start=3.0, kind='B'),
        SimObject((1.0, 4.0), (0.9, -0.55), t_start=1.0, kind='C'),
    ), walls=room, laser=LaserSpec())


def crossing_scene() -> Scene:
    """Three pedestrians whose paths cross in front of the scanner, passing 0.6-0.7 m apart."""
    return Scene(objects=(
        SimObject((3.0, -4.0), (0.5, 0.9)),
        SimObject((7.6, -4.6), (-0.5, 0.9)),
        SimObject((2.9, 3.5), (0.8, -0.6), t_start=1.0),
    ), laser=LaserSpec())


MAX_DRAWS = 200          # draws per walker before a crowd that cannot fit is refused


def crowd_scene(n: int = 20, seed: int = 5, beams: int = 361, fov_deg: float = 180.0,
                range_max: float = 13.0, clutter: float = 0.0,
                seconds: float | None = None) -> Scene:
    """
    ``n`` pedestrians walking in random directions in front of the scanner.

    With ``seconds``, a walker whose bounding circle would overlap that of one drawn
    before it in that time is drawn again, so that nobody walks through anybody; without
    it walkers may pass through one another (the timing benchmarks).

    Raises
    ------
    ValueError
        If ``MAX_DRAWS`` draws a walker leave the crowd short of ``n`` (too many for the
        space and time).
    """
    rng = np.random.default_rng(seed)
    times = _gap_times(seconds) if seconds is not None else None
    objs, tracks = [], []
    draws = 0
    while len(objs) < n:
        draws += 1
        if draws > MAX_DRAWS * n:
            raise ValueError(f'crowd_scene: only {len(objs)} of {n} walkers fit without '
                             f'overlapping in {seconds} s ({MAX_DRAWS * n} draws)')
        r = rng.uniform(1.5, range_max * 0.8)
        a = rng.uniform(-math.radians(fov_deg) / 2 * 0.9, math.radians(fov_deg) / 2 * 0.9)
        h = rng.uniform(-math.pi, math.pi)
        speed = rng.uniform(0.3, 1.4)
        ob = SimObject((r * math.cos(a), r * math.sin(a)),
                       (speed * math.cos(h), speed * math.sin(h)))
        if times is not None:
            track = ob.centres(times)
            if any(_gap(track, ob.radius, other, o.radius) < 0.0
                   for other, o in zip(tracks, objs)):
                continue
            tracks.append(track)
        objs.append(ob)
    half = math.radians(fov_deg) / 2
    return Scene(tuple(objs), laser=LaserSpec(angle_min=-half, angle_max=half, n_beams=beams,
                                              range_max=range_max, clutter_per_scan=clutter))


def clutter_scene() -> Scene:
    """The tutorial's people with 15 clutter returns per scan."""
    base = tutorial_scene()
    from dataclasses import replace as _replace

    return _replace(base, laser=_replace(base.laser, clutter_per_scan=15.0))
