"""
Planar poses, the transform buffer, and the queue of scans waiting for their transform:
checked against poses composed by hand (rotation matrices), and each way a transform
can fail.
"""
import math

import numpy as np
import pytest

from extended_tracker.filter.mixture import Mixture
from extended_tracker.frames.buffer import (
    ConnectivityError, ExtrapolationError, planar, TiltError, Transform, TransformBuffer,
)
from extended_tracker.frames.placing import ScanPlacer
from extended_tracker.frames.pose import kinematics_to_inner, mixture_to_inner, Pose2

S = 1_000_000_000


def matrix(p: Pose2) -> np.ndarray:
    """The homogeneous 3 x 3 matrix of a planar pose."""
    c, s = math.cos(p.yaw), math.sin(p.yaw)
    return np.array([[c, -s, p.x], [s, c, p.y], [0, 0, 1.0]])


def pose_of(M: np.ndarray) -> Pose2:
    return Pose2(M[0, 2], M[1, 2], math.atan2(M[1, 0], M[0, 0]))


def close(a: Pose2, b: Pose2, tol=1e-9) -> bool:
    return (abs(a.x - b.x) < tol and abs(a.y - b.y) < tol
            and abs(math.remainder(a.yaw - b.yaw, 2 * math.pi)) < tol)


def quat(yaw, roll=0.0):
    """(x, y, z, w) of a yaw after a roll."""
    cr, sr, cy, sy = math.cos(roll / 2), math.sin(roll / 2), math.cos(yaw / 2), math.sin(yaw / 2)
    return (sr * cy, sr * sy, cr * sy, cr * cy)


A, B = Pose2(1.0, -2.0, 0.7), Pose2(-0.3, 0.5, -2.9)


def test_poses_compose_and_invert_as_their_matrices():
    assert close(A.compose(B), pose_of(matrix(A) @ matrix(B)))
    assert close(A.inverse(), pose_of(np.linalg.inv(matrix(A))))
    pts = np.array([[0.0, 0.0], [2.0, 1.0], [-1.0, 3.0]])
    h = np.c_[pts, np.ones(3)]
    assert np.allclose(A.to_outer(pts), (matrix(A) @ h.T).T[:, :2])
    assert np.allclose(A.to_inner(A.to_outer(pts)), pts)
    assert Pose2().to_outer(pts) is pts                     # the identity moves nothing


def test_a_mixture_seen_from_the_scanner_is_its_samples_moved():
    """Monte Carlo oracle: samples of N(m, P) moved into the scanner's frame have the
    moved mean and covariance; the extent turns with the axes."""
    rng = np.random.default_rng(1)
    m = np.array([[3.0, 1.0, 0.5, -0.2]])
    L = rng.normal(size=(4, 4)) * 0.3
    P = (L @ L.T + 0.05 * np.eye(4))[None]
    V = np.array([[[0.4, 0.1], [0.1, 0.2]]])
    m_in, P_in, V_in = kinematics_to_inner(A, m, P, V)
    x = rng.multivariate_normal(m[0], P[0], size=200_000)
    R = A.rotation
    moved = np.c_[A.to_inner(x[:, :2]), x[:, 2:] @ R]
    assert np.allclose(moved.mean(axis=0), m_in[0], atol=0.01)
    assert np.allclose(np.cov(moved.T), P_in[0], atol=0.01)
    assert np.allclose(V_in[0], R.T @ V[0] @ R)
    mix = Mixture(np.ones(1), np.ones(1), np.ones(1), m, P, np.full(1, 10.0), V,
                  np.zeros(1, np.int64))
    assert np.allclose(mixture_to_inner(A, mix).m, m_in)
    assert mixture_to_inner(Pose2(), mix) is mix


def tree(buffer: TransformBuffer, t0=0, t1=S):
    """map -> odom (static), odom -> base (moving: B at t0 to A at t1), base -> laser."""
    buffer.set_transform('map', 'odom', 0, (5.0, 0.0, 0.0), quat(0.3), static=True)
    for t, p in ((t0, B), (t1, A)):
        buffer.set_transform('odom', 'base', t, (p.x, p.y, 0.0), quat(p.yaw))
    buffer.set_transform('base', 'laser', 0, (0.2, 0.0, 0.3), quat(0.0), static=True)


def test_a_chain_is_composed_and_interpolated_at_the_stamp():
    buffer = TransformBuffer()
    tree(buffer)
    mount, odom = Pose2(0.2, 0.0, 0.0), Pose2(5.0, 0.0, 0.3)
    for s in (0.0, 0.25, 1.0):
        base = Pose2(B.x + s * (A.x - B.x), B.y + s * (A.y - B.y),
                     B.yaw + s * math.remainder(A.yaw - B.yaw, 2 * math.pi))
        got = planar(buffer.lookup('map', 'laser', int(s * S)), 0.1)
        assert close(got, odom.compose(base).compose(mount), 1e-9)
    # the other way round, and between two leaves
    back = planar(buffer.lookup('laser', 'odom', S // 2), 0.1)
    assert close(back, planar(buffer.lookup('odom', 'laser', S // 2), 0.1).inverse())
    assert close(planar(buffer.lookup('laser', 'laser', 7), 0.1), Pose2())


def test_lookups_outside_the_data_say_which_side_and_unknown_frames_say_so():
    buffer = TransformBuffer()
    tree(buffer, S, 2 * S)
    with pytest.raises(ExtrapolationError) as late:
        buffer.lookup('odom', 'laser', 3 * S)
    assert late.value.future
    with pytest.raises(ExtrapolationError) as early:
        buffer.lookup('odom', 'laser', 0)
    assert not early.value.future
    with pytest.raises(ConnectivityError, match='no transform links'):
        buffer.lookup('odom', 'camera', S)
    buffer.set_transform('world', 'other', 0, (0, 0, 0), quat(0), static=True)
    with pytest.raises(ConnectivityError):
        buffer.lookup('odom', 'other', S)
    # a static link answers at any time
    assert buffer.lookup('base', 'laser', 123).translation[0] == 0.2
    with pytest.raises(ValueError):
        buffer.set_transform('odom', 'base', S, (0, 0, 0), (0, 0, 0, 0))
    with pytest.raises(ValueError):
        buffer.set_transform('odom', 'odom', S, (0, 0, 0), quat(0))


def test_the_live_buffer_keeps_ten_seconds():
    buffer = TransformBuffer()
    for k in range(30):
        buffer.set_transform('odom', 'base', k * S, (k, 0, 0), quat(0))
    with pytest.raises(ExtrapolationError) as old:
        buffer.lookup('odom', 'base', 5 * S)
    assert not old.value.future
    assert buffer.lookup('odom', 'base', 25 * S).translation[0] == 25
    offline = TransformBuffer(cache_ns=None)
    for k in range(30):
        offline.set_transform('odom', 'base', k * S, (k, 0, 0), quat(0))
    assert offline.lookup('odom', 'base', 5 * S).translation[0] == 5


def test_a_tilted_scanner_is_refused_and_a_slight_tilt_projected():
    tf = Transform(np.array([1.0, 2.0, 0.5]), np.array(quat(0.8, roll=0.3)))
    with pytest.raises(TiltError, match='tilted 17.2 deg'):
        planar(tf, 0.1)
    slight = planar(Transform(np.array([1.0, 2.0, 0.5]), np.array(quat(0.8, roll=0.05))), 0.1)
    assert close(slight, Pose2(1.0, 2.0, 0.8), 1e-12)


class Clock:
    def __init__(self):
        self.buffer = TransformBuffer()

    def placer(self, timeout=0.2):
        return ScanPlacer(self.buffer.lookup, 'odom', timeout, 0.1)


def test_a_scan_waits_for_its_transform_then_is_placed_at_its_stamp():
    c = Clock()
    c.buffer.set_transform('odom', 'laser', 0, (0, 0, 0), quat(0))
    q = c.placer()
    q.push('scan1', S, 'laser', S)
    q.push('scan2', S + S // 10, 'laser', S + S // 10)
    assert q.ready(S + S // 10) == []                       # its transform is not there yet
    c.buffer.set_transform('odom', 'laser', 2 * S, (2.0, 0, 0), quat(0))
    out = q.ready(S + S // 5)
    assert [p.scan for p in out] == ['scan1', 'scan2']       # in order
    assert out[0].place.frame == 'odom' and close(out[0].place.pose, Pose2(1.0, 0, 0))
    assert close(out[1].place.pose, Pose2(1.1, 0, 0)) and not out[1].dropped


def test_a_transform_that_never_comes_drops_the_scan_after_the_timeout():
    c = Clock()
    c.buffer.set_transform('odom', 'laser', 0, (0, 0, 0), quat(0))
    q = c.placer(timeout=0.2)
    q.push('s', S, 'laser', S)
    assert q.ready(S + S // 10) == []
    (late,) = q.ready(S + S // 5)
    assert late.dropped and late.event == 'transform_late' and 'after that' in late.error
    # one older than what is kept: dropped at once
    for k in range(1, 15):
        c.buffer.set_transform('odom', 'laser', k * S, (k, 0, 0), quat(0))
    q.push('old', S, 'laser', 14 * S)
    (old,) = q.ready(14 * S)
    assert old.dropped and old.event == 'transform_missing' and 'before that' in old.error


def test_no_link_at_all_tracks_in_the_scan_frame_until_one_appears():
    c = Clock()
    q = c.placer(timeout=0.2)
    q.push('a', S, 'laser', S)
    assert q.ready(S) == []                                 # TF may come at start-up
    (a,) = q.ready(S + S // 5)
    assert a.place is None and not a.dropped and a.event == 'no_fixed_frame'
    q.push('b', 2 * S, 'laser', 2 * S)
    (b,) = q.ready(2 * S)
    assert b.place is None and b.event is None               # said once
    c.buffer.set_transform('odom', 'laser', 0, (1, 0, 0), quat(0), static=True)
    q.push('c', 3 * S, 'laser', 3 * S)
    (cc,) = q.ready(3 * S)
    assert cc.event == 'fixed_frame_found' and cc.place.frame == 'odom'
    # linked once: a frame that loses its link is dropped, not tracked elsewhere
    q.push('d', 4 * S, 'camera', 4 * S)
    (d,) = q.ready(4 * S)
    assert d.dropped and d.event == 'transform_missing'


def test_a_tilted_mount_drops_its_scans_with_the_angle():
    c = Clock()
    c.buffer.set_transform('odom', 'laser', 0, (0, 0, 0), quat(0, roll=0.5), static=True)
    q = c.placer()
    q.push('s', S, 'laser', S)
    (s,) = q.ready(S)
    assert s.dropped and s.event == 'tilted_scanner' and '28.6 deg' in s.error
