"""
Several scanners placed in one fixed frame feed one tracker: each with its own shadows,
its own background on its own clock, and the others' fields of view keeping what it
cannot see.
"""
import math

import numpy as np
import pytest
from rclpy.qos import qos_profile_sensor_data

from extended_tracker.config import from_dict
from extended_tracker.evaluation.metrics import score_sequence
from extended_tracker.frames.pose import Pose2
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.scanners import View
from extended_tracker.sim.two_scanners import two_scanner_scans

CFG = from_dict({'model': {'clutter_density': 'beam'}})


def run(only=None):
    """The two-scanner scene through the pipeline (only one scanner's scans with
    ``only``): the results, the GOSPA score and the ids on the circling person."""
    state, results, truth_seq, est_seq, circling = PipelineState.initial(CFG), [], [], [], []
    for scan, truth, place in two_scanner_scans(12.0, 8):
        if only and scan.header.frame_id != only:
            continue
        state, res = step(state, scan, CFG, place=place)
        results.append(res)
        e = res.estimates
        truth_seq.append(([o.id for o in truth], np.array([o.centre for o in truth]),
                          np.array([o.extent for o in truth])))
        est_seq.append((e.label.tolist(), e.m[:, :2], e.X))
        person = next(o for o in truth if o.kind == 'circling')
        if len(e) and np.min(np.linalg.norm(e.m[:, :2] - person.centre, axis=1)) < 0.7:
            circling.append(int(e.label[np.argmin(np.linalg.norm(e.m[:, :2] - person.centre,
                                                                 axis=1))]))
    score, _ = score_sequence(truth_seq, est_seq, 2.0, 2.0)
    return state, results, score, circling


@pytest.fixture(scope='module')
def both():
    return run()


def test_a_person_circling_the_robot_keeps_one_id_across_the_seams(both):
    _, results, score, circling = both
    assert len(circling) > 0.85 * len(results) and len(set(circling)) == 1
    assert score.id_switches == 0 and score.false_mean == 0.0


def test_two_scanners_track_better_than_either_alone(both):
    """The oracle is each scanner alone: together they score better than either, and
    keep the circling person in scans where either alone has lost it behind its back."""
    _, results, together, circling = both
    for only in ('front_laser', 'rear_laser'):
        _, alone_results, alone, alone_circling = run(only)
        assert together.gospa_mean < alone.gospa_mean - 0.3
        assert len(alone_circling) / len(alone_results) < len(circling) / len(results) - 0.15


def test_each_scanner_keeps_its_own_background_and_pose(both):
    """Scans of the two scanners alternate without a layout change or a restart; each
    scanner's per-beam background is its own (its beams), learned on its own clock."""
    state, results, _, _ = both
    assert not [r.event for r in results if r.event]
    assert state.scanner in ('front_laser', 'rear_laser') and len(state.others) == 1
    (other,) = state.others.values()
    for bg in (state.background, other.background):
        assert len(bg.angles) == 541 and np.isfinite(bg.background).mean() > 0.9
    assert {r.frame_id for r in results} == {'base_link'}


def test_a_view_sees_its_sector_out_to_its_range():
    view = View(Pose2(1.0, 0.0, math.pi / 2), -0.75 * math.pi, 0.75 * math.pi, 5.0, False)
    pts = np.array([[1.0, 3.0],        # ahead
                    [1.0, -0.5],       # right behind it: outside 270 deg
                    [1.0, 7.0],        # ahead, beyond range
                    [-2.0, 0.0]])      # to its left
    assert view.sees(pts).tolist() == [True, False, False, True]
    full = View(Pose2(), -math.pi, math.pi, 5.0, True)
    assert full.sees(pts).tolist() == [True, True, False, True]


# --- bags of several scanners ---

@pytest.fixture(scope='module')
def two_bag(tmp_path_factory):
    from extended_tracker.sim.bag import write_sim_bag

    out = tmp_path_factory.mktemp('two') / 'two'
    write_sim_bag(out, 'two_scanners', seed=8, duration=6.0)
    return out


def test_a_bag_of_two_scanners_is_replayed_as_one_tracker(two_bag, tmp_path):
    """Both topics tracked in the frame the bag's /tf_static links them through; the
    output holds both scan topics and one /tracks; the tracks are those of the
    pipeline fed both scanners in stamp order."""
    from rosbags.rosbag2 import Reader

    from extended_tracker.bag.bagio import message_typestore
    from extended_tracker.bag.replay import replay
    from extended_tracker.config import TrackerConfig

    s = replay(two_bag, tmp_path / 'out', TrackerConfig(), progress=False)
    assert s.topic == '/front_laser/scan, /rear_laser/scan' and s.scans == 120
    assert s.fixed_frame == 'base_link' and not s.events and s.distinct_ids == 3
    store = message_typestore()
    with Reader(tmp_path / 'out') as r:
        topics = {c.topic for c in r.connections}
        tracks = [store.deserialize_cdr(raw, c.msgtype)
                  for c, _, raw in r.messages([c for c in r.connections
                                               if c.topic == '/tracks'])]
    assert {'/front_laser/scan', '/rear_laser/scan', '/tracks', '/tf_static'} <= topics
    state, cfg = PipelineState.initial(TrackerConfig()), TrackerConfig()
    for msg, (scan, _, place) in zip(tracks, two_scanner_scans(6.0, 8)):
        state, res = step(state, scan, cfg, place=place)
        got = np.array([[o.position.x, o.position.y] for o in msg.objects]).reshape(-1, 2)
        assert msg.header.frame_id == 'base_link'
        assert np.allclose(got, res.estimates.m[:, :2], atol=1e-6)


def test_scanners_nothing_links_need_their_mounts(two_bag, tmp_path):
    """Without the mounts in the bag: refused with what to do; with a mounts file: placed
    on its base frame."""
    import shutil

    import yaml

    from extended_tracker.bag.replay import replay
    from extended_tracker.bag.scanners import load_mounts
    from extended_tracker.config import TrackerConfig
    from extended_tracker.errors import BagError
    from extended_tracker.sim.two_scanners import MOUNTS

    bare = tmp_path / 'bare'
    _copy_without_transforms(two_bag, bare)
    with pytest.raises(BagError, match='give their mounts .--mounts FILE. or one --scan-topic'):
        replay(bare, tmp_path / 'out', TrackerConfig(), progress=False)
    file = tmp_path / 'mounts.yaml'
    file.write_text(yaml.safe_dump({'base_frame': 'robot', 'mounts': {
        f: [p.x, p.y, p.yaw] for f, p in MOUNTS.items()}}))
    s = replay(bare, tmp_path / 'out', TrackerConfig(), progress=False,
               mounts=load_mounts(file))
    assert s.fixed_frame == 'robot' and s.frame_why == 'the mounts place the scanners on it'
    assert s.distinct_ids == 3 and not s.events
    for text, why in (('base_frame: robot\n', 'KeyError'), ('[1, 2]\n', 'TypeError'),
                      ('base_frame: ""\nmounts: {a: [0, 0, 0]}\n', 'must name a frame'),
                      ('base_frame: r\nmounts: {a: [0, x, 0]}\n', 'ValueError')):
        file.write_text(text)
        with pytest.raises(BagError, match=why):
            load_mounts(file)
    shutil.rmtree(tmp_path / 'out')


def _copy_without_transforms(src, dst):
    """The bag ``src`` without its /tf_static, at ``dst``."""
    from rosbags.rosbag2 import Reader, StoragePlugin, Writer

    with Reader(src) as r, Writer(dst, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, msgdef=c.msgdef.data,
                                        rihs01=c.digest)
                 for c in r.connections if c.topic != '/tf_static'}
        for c, t, raw in r.messages():
            if c.id in conns:
                w.write(conns[c.id], t, raw)


def node_against_pipeline(h, seconds: float):
    """Feed the two-scanner scans to the node under ``h`` on ``front/scan`` and
    ``rear/scan`` in stamp order, each reply checked against the pipeline's estimates on
    the same scans; returns the last reply."""
    from sensor_msgs.msg import LaserScan

    from extended_tracker.ros.testing import laser_scan
    from extended_tracker.sim.two_scanners import MOUNTS

    pubs = {f: h.probe.create_publisher(LaserScan, f'{f.split("_")[0]}/scan',
                                        qos_profile_sensor_data) for f in MOUNTS}
    h.spin_until(lambda: all(p.get_subscription_count() for p in pubs.values()))
    state = PipelineState.initial(CFG)
    for scan, _, place in two_scanner_scans(seconds, 8):
        n = len(h.tracks)
        pubs[scan.header.frame_id].publish(laser_scan(scan))
        assert h.spin_until(lambda: len(h.tracks) > n)
        state, res = step(state, scan, CFG, place=place)
        reply = h.tracks[-1]
        got = np.array([[o.position.x, o.position.y] for o in reply.objects])
        assert reply.header.frame_id == 'base_link'
        assert np.allclose(got.reshape(-1, 2), res.estimates.m[:, :2], atol=1e-6)
    return reply


NODE_PARAMS = {'scan_topics': ['front/scan', 'rear/scan'], 'tf.fixed_frame': 'base_link',
               'model.clutter_density': 'beam'}


def test_the_node_tracks_two_scan_topics_as_one():
    """scan_topics with the two corner scanners, their mounts on /tf_static, the fixed
    frame base_link: one tracks stream, the pipeline's on the merged scans."""
    from extended_tracker.ros.testing import NodeHarness
    from extended_tracker.sim.two_scanners import MOUNTS

    with NodeHarness(NODE_PARAMS) as h:
        for frame, m in MOUNTS.items():
            h.send_transform('base_link', frame, m.x, m.y, m.yaw, static=True)
        reply = node_against_pipeline(h, 3.0)
        assert h.node.counts == {} and len(reply.objects) >= 2


def test_scan_topics_must_name_topics():
    from extended_tracker.errors import ConfigError
    from extended_tracker.ros.testing import NodeHarness

    with pytest.raises(ConfigError, match='scan_topics must name at least one topic'):
        NodeHarness({'scan_topics': ['']})


def test_a_scanner_that_goes_silent_is_said_once_and_heard_again():
    """The rear scanner's topic stops from 3 s to 7 s: once its last scan is timing.max_gap
    old, the front scanner's scan says so (event scanner_silent, once), the rear's view
    no longer keeps what the front cannot see, and tracking goes on; the rear's scans are
    taken again when they come back."""
    state, events, fronts_only = PipelineState.initial(CFG), [], []
    for scan, _, place in two_scanner_scans(10.0, 8):
        t = (scan.header.stamp.sec * 10**9 + scan.header.stamp.nanosec - 1_700_000_000 * 10**9) * 1e-9
        rear = scan.header.frame_id == 'rear_laser'
        if rear and 3.0 <= t < 7.0:
            continue
        state, res = step(state, scan, CFG, place=place)
        if res.event:
            events.append((round(t, 2), res.event, res.error))
        if 5.5 <= t < 7.0:
            fronts_only.append(len(res.estimates))
    assert [e[:2] for e in events] == [(5.0, 'scanner_silent')]
    assert 'no scan from rear_laser' in events[0][2] and 'with front_laser' in events[0][2]
    assert min(fronts_only) >= 1
    assert not state.others[next(iter(state.others))].silent   # heard again at the end


def test_scanners_at_different_rates_take_turns_as_their_stamps_fall():
    """The rear scanner at 12.5 Hz, the front at 10: the scans interleave unevenly
    (sometimes two of one in a row), and nothing restarts; the circling person keeps
    one id."""
    from extended_tracker.sim.two_scanners import two_scanner_scenes

    state, frames, ids = PipelineState.initial(CFG), [], set()
    scenes = two_scanner_scenes(rates=(10.0, 12.5))
    for scan, truth, place in two_scanner_scans(8.0, 8, scenes):
        state, res = step(state, scan, CFG, place=place)
        assert res.event is None, res.error
        frames.append(scan.header.frame_id)
        person = next(o for o in truth if o.kind == 'circling')
        e = res.estimates
        if len(e) and np.min(np.linalg.norm(e.m[:, :2] - person.centre, axis=1)) < 0.7:
            ids.add(int(e.label[np.argmin(np.linalg.norm(e.m[:, :2] - person.centre,
                                                          axis=1))]))
    assert frames.count('rear_laser') == 100 and frames.count('front_laser') == 80
    assert any(a == b == 'rear_laser' for a, b in zip(frames, frames[1:]))
    assert len(ids) == 1


def test_mounts_given_as_parameters_place_the_scanners():
    """No /tf_static: the node's mounts parameter places the two scanners on base_link,
    and the tracks are those of the transforms published; a malformed entry is refused
    at start-up."""
    from extended_tracker.errors import ConfigError
    from extended_tracker.ros.testing import NodeHarness
    from extended_tracker.sim.two_scanners import MOUNTS

    mounts = [f'base_link {f} {m.x!r} {m.y!r} {m.yaw!r}' for f, m in MOUNTS.items()]
    with NodeHarness({**NODE_PARAMS, 'mounts': mounts}) as h:
        node_against_pipeline(h, 2.0)
        assert h.node.counts == {}
    with pytest.raises(ConfigError, match='"PARENT CHILD X Y YAW"'):
        NodeHarness({'mounts': ['base_link front_laser 0.3 0.2']})


def test_a_mount_that_disagrees_with_the_scans_is_said_once():
    """The rear scanner's mount 5 degrees off: the two scanners see the room's walls
    about 0.2 m apart, event mount_mismatch (once); placed right, 0.01 m, nothing said."""
    from extended_tracker.frames.pose import Placement
    from extended_tracker.scanners import mount_disagreement

    for error, said in ((0.09, 1), (0.0, 0)):
        state, events = PipelineState.initial(CFG), []
        for scan, _, place in two_scanner_scans(12.0, 8):
            if scan.header.frame_id == 'rear_laser':
                p = place.pose
                place = Placement(place.frame, Pose2(p.x, p.y, p.yaw + error))
            state, res = step(state, scan, CFG, place=place)
            events += [res.error for r in [res] if r.event == 'mount_mismatch']
        gap, pair = mount_disagreement(state)
        assert len(events) == said and pair == 'front_laser and rear_laser'
        assert (gap > 0.15 and 'their mounts' in events[0]) if said else gap < 0.03
