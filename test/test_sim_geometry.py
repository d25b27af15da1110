"""
The laser simulator against what is worked out apart from it: ray casting against a march
along every beam, walls against their closed form, motion against integrating the
velocity, the truth's extent against samples of the filled shape, and the noise, dropout
and clutter against their statistics. Every figure of the results table comes from it.
The point simulator, on which the filter-core scenario tests run, against its
measurement model's moments.
"""

import math

import numpy as np
import pytest

from extended_tracker.sim.laser import LaserSpec, Scene, SimObject, simulate

CLEAN = LaserSpec(noise_std=0.0, dropout=0.0)
MARCH = 2e-4                 # m between the points a beam is marched through


def first_scan(scene):
    (scan, truth), = simulate(scene, 1.0 / scene.laser.rate_hz, seed=0)
    return scan, truth


def beam_directions(scan):
    n = len(scan.ranges)
    a = scan.angle_min + scan.angle_increment * np.arange(n)
    return np.column_stack([np.cos(a), np.sin(a)])


def local(ob, p):
    """Points ``p`` (..., 2) in the object's own axes at t = 0 (heading from its velocity)."""
    h = math.atan2(ob.velocity[1], ob.velocity[0]) if any(ob.velocity) else 0.0
    d = p - np.asarray(ob.start)
    c, s = math.cos(h), math.sin(h)
    return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], -1)


def level(ob, p):
    """1 on the shape's outline, below 1 inside it: the ellipse's quadratic form, or the
    rectangle's larger scaled half-side."""
    u = local(ob, p)
    if ob.shape == 'rectangle':
        return np.maximum(np.abs(u[..., 0]) / (ob.a / 2), np.abs(u[..., 1]) / (ob.b / 2))
    return (u[..., 0] / ob.a) ** 2 + (u[..., 1] / ob.b) ** 2


def first_inside(ob, d, upto):
    """Per beam, the first marched range (< ``upto``) inside the shape, or inf."""
    t = np.arange(MARCH, upto, MARCH)
    out = np.full(len(d), np.inf)
    for i in range(0, len(d), 16):
        inside = level(ob, t[None, :, None] * d[i:i + 16, None, :]) < 1.0
        hit = inside.any(axis=1)
        out[i:i + 16] = np.where(hit, t[inside.argmax(axis=1)], np.inf)
    return out


SHAPES = [
    SimObject((3.0, 1.0), (0.6, 0.8), a=0.3, b=0.2),                      # a walker
    SimObject((4.0, -2.5), (-3.5, 0.5), a=0.9, b=0.3),                    # a bicycle
    SimObject((6.0, 2.0), (1.0, -1.0), shape='rectangle', a=4.5, b=1.8),   # a car
    SimObject((2.5, -0.5), (0.0, 0.0), shape='rectangle', a=0.8, b=1.6),   # a cabinet
]


@pytest.mark.slow
@pytest.mark.parametrize('ob', SHAPES, ids=['walker', 'bicycle', 'car', 'standing box'])
def test_every_beam_returns_where_it_first_meets_the_shape(ob):
    scan, truth = first_scan(Scene((ob,), laser=CLEAN))
    d = beam_directions(scan)
    r = scan.ranges.astype(float)
    hit = np.isfinite(r)
    # the returns lie on the outline (to float32's rounding of the range) ...
    q = level(ob, r[hit, None] * d[hit])
    np.testing.assert_allclose(q, 1.0, atol=5e-6)
    # ... and no point of the beam before its return is inside the shape; a beam with no
    # return never enters it
    before = first_inside(ob, d, 12.0)
    assert np.all(before[hit] >= r[hit] - 1e-5)
    assert np.all(np.isinf(before[~hit]))
    # the shape is seen: many beams, each counted in the truth
    assert hit.sum() >= 10 and truth[0].visible_beams == hit.sum()


def test_walls_return_their_closed_form_and_nothing_past_their_ends():
    # a wall across x = 3 from y = -1 to y = 2: the beam at angle a meets it at 3 / cos a
    scene = Scene((), walls=(((3.0, -1.0), (3.0, 2.0)),), laser=CLEAN)
    scan, truth = first_scan(scene)
    a = scan.angle_min + scan.angle_increment * np.arange(len(scan.ranges))
    y = 3.0 * np.tan(a)
    on = (np.abs(a) < math.pi / 2 - 1e-9) & (y >= -1.0) & (y <= 2.0)
    assert on.sum() > 40 and truth == []
    np.testing.assert_allclose(scan.ranges[on], 3.0 / np.cos(a[on]), rtol=1e-6)
    assert np.all(np.isinf(scan.ranges[~on]))


def test_the_nearest_shape_returns_and_the_truth_counts_its_beams():
    """A walker in front of a wall and partly in front of another walker; a third beyond
    the range: each object's visible beams are the beams whose return is on it."""
    front = SimObject((2.0, 0.0), a=0.25, b=0.25, kind='standing')
    behind = SimObject((5.0, 0.6), a=0.3, b=0.25, kind='standing')
    far = SimObject((7.3, -11.4), a=0.3, b=0.3, kind='standing')     # 13.5 m away
    scene = Scene((front, behind, far), walls=(((8.0, -6.0), (8.0, 6.0)),), laser=CLEAN)
    scan, truth = first_scan(scene)
    d = beam_directions(scan)
    r = scan.ranges.astype(float)
    p = np.where(np.isfinite(r)[:, None], r[:, None] * d, np.nan)
    wall = np.isclose(p[:, 0], 8.0, atol=1e-5)
    on = [np.isclose(level(ob, p), 1.0, atol=1e-4) for ob in (front, behind, far)]
    # every return is on one of them, and the wall is seen only where nothing is nearer
    assert np.all(wall | on[0] | on[1] | ~np.isfinite(r))
    counts = [t.visible_beams for t in truth]
    assert counts == [int(on[0].sum()), int(on[1].sum()), 0]
    # partly hidden: fewer beams than it spans alone
    alone, _ = first_scan(Scene((behind,), laser=CLEAN))
    assert 0 < counts[1] < np.isfinite(alone.ranges).sum()
    # the far walker is still in the truth (a tracker may keep it), with no beam
    assert [t.kind for t in truth] == ['standing'] * 3


def integrate(ob, t, n=200_000):
    """Centre at ``t`` by the midpoint rule over the velocity: heading ``h0 + w s``,
    speed zero before ``t_start`` and inside the stops."""
    s = (np.arange(n) + 0.5) * (t / n)
    vx, vy = ob.velocity
    speed, h0 = math.hypot(vx, vy), math.atan2(vy, vx)
    moving = s >= ob.t_start
    for a, b in ob.stops:
        moving &= ~((s >= a) & (s < b))
    # the heading turns only while the object moves (at each midpoint: half its own step)
    turned = (np.cumsum(moving) - 0.5 * moving) * (t / n) * ob.turn_rate
    v = speed * moving[:, None] * np.column_stack([np.cos(h0 + turned), np.sin(h0 + turned)])
    return np.asarray(ob.start) + v.sum(axis=0) * (t / n)


@pytest.mark.parametrize('ob', [
    SimObject((1.0, 2.0), (0.8, 0.3), turn_rate=0.4),
    SimObject((-3.0, 0.5), (0.0, -1.2), turn_rate=-0.7, t_start=0.5),
    SimObject((0.0, 0.0), (1.0, 0.5), t_start=1.0, stops=((2.0, 3.0), (4.0, 4.5))),
    SimObject((2.0, 2.0), (0.5, 0.5), turn_rate=0.3, stops=((1.0, 2.5),)),
], ids=['turn', 'turn right, late', 'stops', 'turn with a stop'])
@pytest.mark.parametrize('t', [0.3, 2.2, 3.5, 4.25, 6.0])
def test_the_motion_is_the_integral_of_the_velocity(ob, t):
    c, vel, h = ob.state(t)
    np.testing.assert_allclose(c, integrate(ob, t), atol=2e-5)
    standing = any(a <= t < b for a, b in ob.stops)
    if t < ob.t_start:
        np.testing.assert_array_equal(c, ob.start)        # not yet in the scene
    elif standing:
        assert np.all(vel == 0.0)
    else:
        # the velocity is the derivative of the centre
        dt = 1e-6
        np.testing.assert_allclose(vel, (ob.state(t + dt)[0] - ob.state(t - dt)[0]) / (2 * dt),
                                   atol=1e-5)


@pytest.mark.parametrize('ob', SHAPES[1:3], ids=['ellipse', 'rectangle'])
def test_the_truth_extent_is_four_times_the_filled_shapes_second_moments(ob):
    """The extent convention of the model note: X's ellipse is the outline, and X / 4 the
    second moments of the filled shape (a rectangle's ellipse of equal moments)."""
    _, (truth,) = first_scan(Scene((ob,), laser=CLEAN))
    rng = np.random.default_rng(1)
    half = max(ob.a, ob.b)
    p = np.asarray(ob.start) + rng.uniform(-half, half, (800_000, 2))
    inside = p[level(ob, p) <= 1.0]
    d = inside - inside.mean(axis=0)
    np.testing.assert_allclose(truth.extent, 4 * d.T @ d / len(d),
                               atol=0.01 * np.abs(truth.extent).max())
    np.testing.assert_allclose(truth.centre, ob.start)


def test_noise_and_dropout_have_their_configured_statistics():
    spec = LaserSpec(noise_std=0.05, dropout=0.2)
    scene = Scene((), walls=(((5.0, -20.0), (5.0, 20.0)),), laser=spec)
    runs = simulate(scene, 20.0, seed=3)
    a = spec.angles()
    wall = 5.0 / np.cos(a)
    reach = (np.abs(a) < math.pi / 2 - 1e-9) & (wall < spec.range_max - 0.5)
    r = np.array([scan.ranges for scan, _ in runs])[:, reach].astype(float)
    n = r.size
    dropped = np.isinf(r).mean()
    assert abs(dropped - 0.2) < 4 * math.sqrt(0.2 * 0.8 / n)
    err = (r - wall[reach])[np.isfinite(r)]
    assert abs(err.mean()) < 4 * 0.05 / math.sqrt(len(err))
    assert abs(err.std() / 0.05 - 1.0) < 0.03
    # the stamps and the scan's geometry
    scans = [scan for scan, _ in runs]
    ns = [s.header.stamp.sec * 10**9 + s.header.stamp.nanosec for s in scans]
    assert np.all(np.diff(ns) == 100_000_000) and len(scans) == 200
    assert scans[0].angle_increment == pytest.approx(math.pi / 360)


def test_clutter_is_poisson_per_scan_and_uniform_in_front_of_what_a_beam_hits():
    spec = LaserSpec(noise_std=0.0, dropout=0.0, clutter_per_scan=4.0)
    scene = Scene((), walls=(((5.0, -20.0), (5.0, 20.0)),), laser=spec)
    a = spec.angles()
    with np.errstate(divide='ignore'):
        wall = np.where(np.abs(a) < math.pi / 2 - 1e-9, 5.0 / np.cos(a), np.inf)
    limit = np.minimum(wall, spec.range_max)
    counts, u = [], []
    for scan, _ in simulate(scene, 100.0, seed=4):
        r = scan.ranges.astype(float)
        front = np.isfinite(r) & (r < np.where(np.isfinite(wall) & (wall <= spec.range_max),
                                              wall, np.inf) - 1e-4)
        counts.append(front.sum())
        u.extend(((r[front] - spec.range_min) / (limit[front] - spec.range_min)).tolist())
    counts, u = np.array(counts), np.array(u)
    # mean and variance of a Poisson count of 4 over 1000 scans (a return drawn right at
    # the wall is missed, one in thousands)
    assert abs(counts.mean() - 4.0) < 4 * math.sqrt(4.0 / len(counts))
    assert abs(counts.var() / 4.0 - 1.0) < 0.15
    # uniform between range_min and the beam's own return (or the range)
    assert np.all((u >= 0.0) & (u <= 1.0))
    assert abs(u.mean() - 0.5) < 4 * math.sqrt(1 / 12 / len(u))
    assert abs(u.var() * 12 - 1.0) < 0.06


def test_the_point_simulator_draws_from_the_measurement_model():
    """
    ``sim.points``: an object alive at ``t`` (``t_start`` to ``t_end``, both included) is
    at ``start + velocity (t - t_start)`` and yields Poisson(rate) points from
    N(centre, rho X + sigma^2 I); a missed one yields none and is in the truth all the
    same; clutter is Poisson(clutter_rate) points uniform in the box. Checked against
    sample moments of 4000 scans (tolerances some five standard errors).
    """
    from extended_tracker.sim.points import point_scene, PointObject

    X = np.array([[0.36, 0.1], [0.1, 0.09]])
    ob = PointObject((1.0, 2.0), (0.5, -0.25), extent=tuple(map(tuple, X)), rate=8.0,
                     t_start=2.0, t_end=6.0)
    centre = np.array([2.0, 1.5])                             # 2 s after its start
    rng = np.random.default_rng(0)
    draws = [point_scene([ob], 4.0, rng, rho=0.25, sigma=0.05, clutter_rate=0.0)
             for _ in range(4000)]
    counts = np.array([len(pts) for pts, _ in draws])
    assert abs(counts.mean() - 8.0) < 0.25 and abs(counts.var() - 8.0) < 1.0
    pts = np.vstack([pts for pts, _ in draws])
    assert np.abs(pts.mean(axis=0) - centre).max() < 0.01
    np.testing.assert_allclose(np.cov(pts.T), 0.25 * X + 0.0025 * np.eye(2), atol=0.004)
    (i, c), = draws[0][1]
    assert i == 0 and np.allclose(c, centre)
    for t, alive in ((1.99, False), (2.0, True), (6.0, True), (6.01, False)):
        pts, truth = point_scene([ob], t, rng, clutter_rate=0.0)
        assert (len(truth) == 1) == alive and (alive or len(pts) == 0), t
    pts, truth = point_scene([ob], 4.0, rng, clutter_rate=0.0, missed=(0,))
    assert len(pts) == 0 and len(truth) == 1
    # clutter alone (the object gone): 3 a scan, uniform in a 4 m x 6 m box
    box = ((-1.0, -2.0), (3.0, 4.0))
    draws = [point_scene([ob], 10.0, rng, clutter_rate=3.0, box=box)[0] for _ in range(4000)]
    assert abs(np.mean([len(d) for d in draws]) - 3.0) < 0.15
    pts = np.vstack(draws)
    assert (pts >= box[0]).all() and (pts <= box[1]).all()
    assert np.abs(pts.mean(axis=0) - [1.0, 1.0]).max() < 0.08
    assert np.abs(pts.var(axis=0) - [16 / 12, 36 / 12]).max() < 0.12


def test_clutter_returns_fall_on_distinct_beams():
    """A Poisson number of clutter returns, each on a beam of its own: with 300 a scan on
    361 beams and nothing else in view, a scan holds as many returns as were drawn (up to
    the beams there are), where beams drawn with replacement would hold some 200."""
    spec = LaserSpec(noise_std=0.0, dropout=0.0, clutter_per_scan=300.0)
    counts = [np.isfinite(scan.ranges).sum() for scan, _ in simulate(Scene((), laser=spec),
                                                                      10.0, seed=2)]
    assert abs(np.mean(counts) - 300.0) < 4 * math.sqrt(300.0 / len(counts))


def test_a_scanner_inside_a_shape_sees_its_far_side():
    """The scanner inside an ellipse (a person leaning on it): every beam returns where it
    leaves the shape, 1 m away on a circle of radius 1 about the scanner."""
    ob = SimObject((0.0, 0.0), a=1.0, b=1.0)
    scan, _ = first_scan(Scene((ob,), laser=CLEAN))
    np.testing.assert_allclose(scan.ranges, 1.0, rtol=1e-6)


def test_an_object_is_alive_from_its_start_to_its_end_inclusive():
    ob = SimObject((3.0, 0.0), t_start=1.0, t_end=2.0)
    assert [ob.alive(t) for t in (0.999, 1.0, 2.0, 2.001)] == [False, True, True, False]
