"""
Transforms in and out: the replay reads a bag's /tf and /tf_static and writes them back
beside the tracks; the node takes them from /tf and /tf_static (or tf2_ros where it is
installed) and publishes in the fixed frame; each way a transform fails is counted.
"""
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from extended_tracker.bag.replay import choose_fixed_frame, replay
from extended_tracker.config import from_dict, TrackerConfig
from extended_tracker.evaluation.evaluate import evaluate_bag
from extended_tracker.frames.buffer import ConnectivityError, ExtrapolationError
from extended_tracker.frames.pose import Placement, Pose2
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.ros.testing import laser_scan as ros_scan, NodeHarness
from extended_tracker.ros.transforms import TransformSource
from extended_tracker.sim.bag import write_sim_bag
from extended_tracker.sim.laser import simulate, tutorial_scene

MOVING = Path(__file__).resolve().parents[2] / 'shared' / 'data' / 'moving'
S = 1_000_000_000


@pytest.fixture(scope='module')
def drive_bag(tmp_path_factory):
    out = tmp_path_factory.mktemp('drive') / 'drive'
    write_sim_bag(out, 'corridor_drive', seed=7, duration=8.0)
    return out


def topics_of(bag):
    from rosbags.rosbag2 import Reader

    with Reader(bag) as r:
        return {c.topic: c for c in r.connections}


def test_a_replay_tracks_in_odom_where_the_bag_links_the_scans_to_it(drive_bag, tmp_path):
    s = replay(drive_bag, tmp_path / 'out', TrackerConfig(), progress=False)
    assert s.fixed_frame == 'odom' and s.frame_why == "the bag's transforms link 'laser' to it"
    assert 'tracked in       odom' in '\n'.join(s.lines()) and not s.events
    conns = topics_of(tmp_path / 'out')
    assert {'/scan', '/tracks', '/tracks/markers', '/tf', '/tf_static'} <= set(conns)
    static_qos = conns['/tf_static'].ext.offered_qos_profiles[0]
    assert static_qos.durability.name == 'TRANSIENT_LOCAL'       # RViz gets it late too
    score, _, _ = evaluate_bag(tmp_path / 'out', drive_bag / 'truth.json')
    assert score.gospa_mean < 1.0          # 0.81 over the first 8 s, warm-up included


def test_the_frame_can_be_chosen_and_a_bag_without_transforms_stays_in_its_own(
        drive_bag, tmp_path):
    cfg = TrackerConfig()
    assert choose_fixed_frame(drive_bag, None, cfg, '')[:2] == ('', 'as asked')
    s = replay(drive_bag, tmp_path / 'own', cfg, progress=False, fixed_frame='')
    assert s.fixed_frame == '' and 'the scan frame' in s.lines()[1]
    still = tmp_path / 'still'
    write_sim_bag(still, 'walls', seed=1, duration=1.0)
    assert choose_fixed_frame(still, None, cfg)[:2] == ('', 'the bag has no transforms')


def test_the_written_transforms_place_the_tracks_as_the_simulator_did(drive_bag, tmp_path):
    """The tracks of the replay (transforms read back from the bag, interpolated) are
    those of the pipeline given the simulator's own poses."""
    from rosbags.rosbag2 import Reader

    from extended_tracker.bag.bagio import message_typestore
    from extended_tracker.sim.drive import corridor_drive_scene

    replay(drive_bag, tmp_path / 'out', TrackerConfig(), progress=False)
    scene = corridor_drive_scene()
    state, direct = PipelineState.initial(TrackerConfig()), []
    for k, (scan, _) in enumerate(simulate(scene, 8.0, seed=7)):
        state, res = step(state, scan, TrackerConfig(),
                          place=Placement('odom', scene.pose(k / scene.laser.rate_hz)))
        direct.append(res)
    store = message_typestore()
    with Reader(tmp_path / 'out') as r:
        conns = [c for c in r.connections if c.topic == '/tracks']
        replayed = [store.deserialize_cdr(raw, c.msgtype) for c, _, raw in r.messages(conns)]
    assert len(replayed) == len(direct)
    for msg, res in zip(replayed, direct):
        assert msg.header.frame_id == 'odom'
        got = np.array([[o.position.x, o.position.y] for o in msg.objects]).reshape(-1, 2)
        assert np.allclose(got, res.estimates.m[:, :2], atol=1e-6)


@pytest.mark.skipif(not MOVING.is_dir(), reason=f'no moving recordings at {MOVING}')
def test_the_moving_recordings_are_tracked_in_odom():
    for bag in sorted(p for p in MOVING.iterdir() if p.is_dir()):
        frame, why = choose_fixed_frame(bag, None, TrackerConfig())[:2]
        assert frame == 'odom', (bag, why)


# --- the node ---

def scans(seconds=2.0):
    return [ros_scan(s) for s, _ in simulate(tutorial_scene(), seconds, seed=3)]


def stamp_of(msg):
    return msg.header.stamp.sec * S + msg.header.stamp.nanosec


def test_the_node_publishes_in_odom_with_a_static_mount():
    """/tf_static odom -> laser (2 m ahead, turned 90 deg): the replies are in odom, the
    estimates those of the pipeline placed at that pose."""
    data = scans()
    pose = Pose2(2.0, 0.0, math.pi / 2)
    state = PipelineState.initial(from_dict({'background': {'enabled': False}}))
    with NodeHarness({'background.enabled': False}) as h:
        assert h.node.transforms.kind == 'own'
        h.send_transform('odom', 'laser', pose.x, pose.y, pose.yaw, static=True)
        for msg in data:
            reply = h.send(msg)
            state, res = step(state, msg, h.node.cfg, place=Placement('odom', pose))
            assert reply.header.frame_id == 'odom'
            got = [[o.position.x, o.position.y] for o in reply.objects]
            assert np.allclose(np.array(got).reshape(-1, 2), res.estimates.m[:, :2])
        assert len(reply.objects) >= 2 and h.node.counts == {}
        values = {kv.key: kv.value for kv in h.diagnostics[-1].status[0].values}
        assert values['frame'] == 'odom (transforms from own)'


def test_without_any_transform_the_node_tracks_in_the_scan_frame_and_says_so():
    with NodeHarness({'background.enabled': False}) as h:
        for msg in scans(0.5):
            reply = h.send(msg)
        assert reply.header.frame_id == 'laser' and h.node.counts == {}
        values = {kv.key: kv.value for kv in h.diagnostics[-1].status[0].values}
        assert "no transform links 'laser' to 'odom'" in values['frame']


def test_a_scan_whose_transform_never_comes_is_dropped_counted_and_answered():
    """The robot's odometry stops after the fifth scan: each later scan waits tf.timeout,
    then is answered with the previous estimates and counted as transform_late."""
    data = scans(1.0)
    with NodeHarness({'background.enabled': False, 'tf.timeout': 0.05}) as h:
        for k, msg in enumerate(data):
            if k < 5:
                for ahead in (0, S // 20):
                    h.send_transform('odom', 'laser', 0.1 * k, 0.0, 0.0, stamp_of(msg) + ahead)
            reply = h.send(msg)
            assert reply.header.frame_id == 'odom'
        assert h.node.counts == {'transform_late': 5}
        values = {kv.key: kv.value for kv in h.diagnostics[-1].status[0].values}
        assert 'no transform odom <- laser' in values['last_reason_transform_late']
        assert h.diagnostics[-1].status[0].message == 'transform_late'


def test_a_tilted_mount_is_refused_per_scan_with_the_angle():
    with NodeHarness({'background.enabled': False}) as h:
        h.send_transform('odom', 'laser', 0.0, 0.0, 0.0, static=True)
        tilt = h._tf_pubs                                # keep the publisher warm
        from geometry_msgs.msg import TransformStamped
        from tf2_msgs.msg import TFMessage

        ts = TransformStamped()
        ts.header.frame_id, ts.child_frame_id = 'odom', 'laser'
        ts.transform.rotation.x, ts.transform.rotation.w = math.sin(0.25), math.cos(0.25)
        before = h.node.transforms.messages
        tilt['/tf_static'].publish(TFMessage(transforms=[ts]))
        h.spin_until(lambda: h.node.transforms.messages > before)
        h.send(scans(0.1)[0])
        assert h.node.counts == {'tilted_scanner': 1}
        assert 'tilted 28.6 deg' in h.node.events.last_reason['tilted_scanner']


class FakeTf2:
    """What the node uses of tf2_ros, to check the wiring where tf2_ros is installed."""

    class LookupException(Exception):
        pass

    class ConnectivityException(Exception):
        pass

    class ExtrapolationException(Exception):
        pass

    def __init__(self, answer):
        self.answer, self.asked, self.listened = answer, [], []
        fake = self

        class Buffer:
            def lookup_transform(self, target, source, time):
                fake.asked.append((target, source, time.nanoseconds))
                if isinstance(fake.answer, Exception):
                    raise fake.answer
                return fake.answer

        class TransformListener:
            def __init__(self, buffer, node):
                fake.listened.append((buffer, node))

        self.Buffer, self.TransformListener = Buffer, TransformListener


def test_tf2_ros_is_used_where_installed_with_its_errors_mapped():
    from geometry_msgs.msg import TransformStamped

    ts = TransformStamped()
    ts.transform.translation.x = 1.5
    ts.transform.rotation.w = 1.0
    node = SimpleNamespace()
    fake = FakeTf2(ts)
    source = TransformSource(node, tf2_ros=fake)
    assert source.kind == 'tf2_ros' and fake.listened == [(source.buffer, node)]
    assert source.lookup('odom', 'laser', 7 * S).translation[0] == 1.5
    assert fake.asked == [('odom', 'laser', 7 * S)]
    for err, kind, future in (
            (fake.ExtrapolationException('Lookup would require extrapolation into the '
                                         'future.'), ExtrapolationError, True),
            (fake.ExtrapolationException('... extrapolation into the past'),
             ExtrapolationError, False),
            (fake.LookupException('"odom" passed to lookupTransform argument target_frame '
                                  'does not exist'), ConnectivityError, None),
            (fake.ConnectivityException('not connected'), ConnectivityError, None)):
        fake.answer = err
        with pytest.raises(kind) as caught:
            source.lookup('odom', 'laser', S)
        if future is not None:
            assert caught.value.future is future


def test_with_a_bag_clock_the_wait_runs_on_the_bag_time():
    """use_sim_time (a bag played with --clock): a scan waits for its transform by the
    bag's clock. While the clock stands, it waits however long; once the clock passes
    its arrival by tf.timeout it is answered, counted transform_late."""
    from rclpy.qos import QoSProfile
    from rosgraph_msgs.msg import Clock

    data = scans(0.3)
    with NodeHarness({'background.enabled': False, 'use_sim_time': True}) as h:
        clock = h.probe.create_publisher(Clock, '/clock', QoSProfile(depth=10))

        def tick(ns):
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = divmod(ns, S)
            clock.publish(msg)
            h.spin_until(lambda: h.node.get_clock().now().nanoseconds == ns)

        t0 = stamp_of(data[0])
        tick(t0)
        h.send_transform('odom', 'laser', 0.0, 0.0, 0.0, t0)
        assert h.send(data[0]).header.frame_id == 'odom'
        n = len(h.tracks)
        h.pub.publish(data[1])              # arrives at t0 by the clock; no transform yet
        assert not h.spin_until(lambda: len(h.tracks) > n, limit=0.5)   # the clock stands
        tick(t0 + S // 10)
        assert not h.spin_until(lambda: len(h.tracks) > n, limit=0.3)   # within the wait
        tick(t0 + S // 2)
        assert h.spin_until(lambda: len(h.tracks) > n)
        assert h.node.counts == {'transform_late': 1}


@pytest.mark.slow
@pytest.mark.skipif(not MOVING.is_dir(), reason=f'no moving recordings at {MOVING}')
def test_the_cars_of_the_moving_recordings_are_tracked_against_motion_capture():
    """Replayed in odom with the defaults: each car the laser sees (3 returns within
    0.3 m) is tracked within 0.2 m on average in most scans it is seen in, by one id in
    the recordings with one car."""
    from extended_tracker.evaluation.recorded import score_recording

    for name, least in (('datmo_intersection', 16), ('datmo_overtake_red', 85)):
        scores, _, frame = score_recording(MOVING / name,
                                           MOVING / f'{name}.ground_truth.csv')
        (s,) = scores.values()
        assert frame == 'odom' and s.tracked >= least and len(s.ids) == 1
        assert np.mean(s.errors) < 0.2


def test_recordings_are_scored_only_where_they_are(tmp_path):
    from extended_tracker.evaluation.recorded import BEGIN, END, write_recorded_results

    page = tmp_path / 'results.md'
    page.write_text(f'# r\n{BEGIN}\nold\n{END}\n')
    assert not write_recorded_results(page, tmp_path / 'none')
    assert page.read_text() == f'# r\n{BEGIN}\nold\n{END}\n'


def test_the_transform_parameters_are_refused_at_run_time():
    from rclpy.parameter import Parameter

    with NodeHarness({'background.enabled': False}) as h:
        (result,) = h.node.set_parameters([Parameter('tf.fixed_frame', value='map')])
        assert not result.successful and 'read at start-up' in result.reason
        assert h.node.cfg.tf.fixed_frame == 'odom'
        (same,) = h.node.set_parameters([Parameter('tf.fixed_frame', value='odom')])
        assert same.successful


def test_the_static_map_keeps_its_cells_in_place_as_it_scrolls():
    """The grid follows the scanner by whole cells: a cell's score stays with its place
    in the fixed frame, and what falls off the edge is forgotten."""
    from extended_tracker.config import BackgroundConfig
    from extended_tracker.sensing.static_map import StaticMap

    cfg = BackgroundConfig(map_radius=2.0)
    smap = StaticMap.around(Pose2(0.0, 0.0, 0.0), cfg)
    here, far = np.array([[0.55, -0.35]]), np.array([[-1.9, 0.0]])
    for p, v in ((here, 1.5), (far, 0.7)):
        ij, _ = smap.index(p)
        smap.score[ij[0, 0], ij[0, 1]] = v
    moved = smap.recentred(Pose2(1.5, 0.5, 0.0), cfg)
    assert moved is not smap and moved.corner != smap.corner
    ij, inside = moved.index(here)
    assert inside[0] and moved.score[ij[0, 0], ij[0, 1]] == np.float32(1.5)
    assert not moved.index(far)[1][0]                     # off the grid now
    assert np.count_nonzero(moved.score) == 1
    assert smap.recentred(Pose2(0.3, 0.2, 1.0), cfg) is smap   # within the middle half
