"""
The node, launch-free, through the package's own harness (``extended_tracker.ros.testing``):
node under test and a probe node in one process, on a private Context with a
SingleThreadedExecutor and bounded spins (DDS on loopback, see conftest).
"""

import copy
from pathlib import Path
import re
import time

import numpy as np
import pytest
from rclpy.parameter import Parameter
import yaml

from extended_tracker.config import from_dict, to_dict, to_flat, TrackerConfig
from extended_tracker.configio import default_yaml, load_yaml
from extended_tracker.errors import ConfigError
from extended_tracker.ros.convert import to_plain
from extended_tracker.ros.node import parameter_descriptors
from extended_tracker.ros.testing import laser_scan as ros_scan, NodeHarness
from extended_tracker.sim.bag import write_sim_bag
from extended_tracker.sim.laser import simulate, tutorial_scene

ROOT = Path(__file__).resolve().parents[1]
YAML = ROOT / 'config' / 'tracker.yaml'
NO_BACKGROUND = {'background.enabled': False}


@pytest.fixture
def harness():
    h = NodeHarness(NO_BACKGROUND)
    yield h
    h.close()


@pytest.mark.slow
def test_tracks_against_simulator_truth(harness):
    data = simulate(tutorial_scene(), 6.0, seed=2)
    for scan, truth in data:
        out = harness.send(ros_scan(scan))
        assert out.header.stamp.sec == scan.header.stamp.sec
        assert out.header.stamp.nanosec == scan.header.stamp.nanosec
        assert out.header.frame_id == 'laser'
    # after the start-up scans every true object has one estimate within 0.5 m
    last = harness.tracks[-1]
    scan, truth = data[-1]
    pos = np.array([[o.position.x, o.position.y] for o in last.objects])
    for t in truth:
        assert np.min(np.linalg.norm(pos - t.centre, axis=1)) < 0.5
    assert len(last.objects) == len(truth)
    ids = {o.id for o in last.objects}
    assert len(ids) == len(last.objects)
    # ids stable over the last 2 s
    for arr in harness.tracks[-20:]:
        assert {o.id for o in arr.objects} == ids
    assert abs(last.expected_count - len(truth)) < 0.5
    assert len(last.cardinality) == TrackerConfig().model.n_max + 1
    assert last.num_detections > 0 and last.processing_time > 0


def test_markers_outline_label_velocity_and_deletion(harness):
    data = simulate(tutorial_scene(), 3.0, seed=1)
    for scan, _ in data:
        harness.send(ros_scan(scan))
    m = harness.markers[-1].markers
    n_obj = len(harness.tracks[-1].objects)
    assert sorted({x.ns for x in m}) == ['label', 'outline', 'velocity']
    assert sum(1 for x in m if x.ns == 'outline') == n_obj
    assert all(len(x.points) == 33 for x in m if x.ns == 'outline')   # closed ellipses
    assert all(x.header.stamp == harness.tracks[-1].header.stamp for x in m)
    # they live a second after the last one sent: a scanner that stops leaves no ghosts
    assert all((x.lifetime.sec, x.lifetime.nanosec) == (1, 0) for x in m)
    # an empty scan: tracks coast; then scans with nothing at all for a while: the
    # vanished ids' markers are deleted
    empty = copy.deepcopy(data[-1][0])
    ranges = np.full(len(empty.ranges), np.inf, dtype=np.float32)
    for k in range(40):
        s = copy.deepcopy(empty)
        ns = s.header.stamp.sec * 10**9 + s.header.stamp.nanosec + (k + 1) * 100_000_000
        s.header.stamp.sec, s.header.stamp.nanosec = ns // 10**9, ns % 10**9
        s.ranges = ranges
        harness.send(ros_scan(s))
    deletes = [x for arr in harness.markers[-40:] for x in arr.markers if x.action == 2]
    assert {x.ns for x in deletes} == {'outline', 'label', 'velocity'}
    assert len(harness.tracks[-1].objects) == 0
    assert not [x for x in harness.markers[-1].markers if x.action == 0]


def test_marker_lifetime_is_a_parameter_and_zero_keeps_them():
    for lifetime, want in ((0.25, (0, 250_000_000)), (0.0, (0, 0))):
        h = NodeHarness(dict(NO_BACKGROUND, **{'extraction.marker_lifetime': lifetime}))
        try:
            for scan, _ in simulate(tutorial_scene(), 1.0, seed=1):
                h.send(ros_scan(scan))
            shown = [x for x in h.markers[-1].markers if x.action == 0]
            assert shown and {(x.lifetime.sec, x.lifetime.nanosec) for x in shown} == {want}
        finally:
            h.close()


@pytest.fixture
def marker_builds(monkeypatch):
    """A list that grows by one each time the node builds a MarkerArray."""
    import extended_tracker.ros.node as node_mod

    built = []
    real = node_mod.markers_data
    monkeypatch.setattr(node_mod, 'markers_data',
                        lambda *a, **k: built.append(1) or real(*a, **k))
    return built


def test_markers_are_built_only_while_someone_listens(marker_builds):
    """No marker subscriber: tracks still come, no markers are built. Once one subscribes,
    markers come with every scan, and ids drawn before the gap that are gone now are
    deleted."""
    built = marker_builds
    h = NodeHarness(NO_BACKGROUND, markers=False)
    try:
        data = simulate(tutorial_scene(), 4.0, seed=1)
        for scan, _ in data[:20]:
            assert h.send(ros_scan(scan)) is not None
        assert len(h.tracks) == 20 and not built and not h.markers
        h.node.marker_ids = {999}                        # an id drawn before the gap
        h.watch_markers()
        for scan, _ in data[20:25]:
            h.send(ros_scan(scan))
        assert len(built) == 5 and len(h.markers) == 5
        first = h.markers[0].markers
        assert {(x.ns, x.id) for x in first if x.action == 2} == {
            ('outline', 999), ('label', 999), ('velocity', 999)}
        assert sum(1 for x in first if x.ns == 'outline' and x.action == 0) == len(
            h.tracks[20].objects)
    finally:
        h.close()


def test_the_rviz_config_shows_what_the_node_publishes(harness):
    """rviz/tracker.rviz subscribes to the node's scan and marker topics with QoS that
    matches, and shows every marker namespace the node publishes."""
    from extended_tracker.report.messages import MARKER_NAMESPACES

    with open(ROOT / 'rviz' / 'tracker.rviz') as f:
        config = yaml.safe_load(f)
    displays = {d['Class']: d for d in config['Visualization Manager']['Displays']}
    laser = displays['rviz_default_plugins/LaserScan']
    assert laser['Topic']['Value'] == harness.node.sub.topic_name == '/scan'
    # best effort takes a reliable or a best-effort scan publisher alike
    assert laser['Topic']['Reliability Policy'] == 'Best Effort'
    markers = displays['rviz_default_plugins/MarkerArray']
    assert markers['Topic']['Value'] == harness.node.pub_markers.topic_name
    assert markers['Topic']['Reliability Policy'] == 'Reliable'      # as the node publishes
    assert set(markers['Namespaces']) == set(MARKER_NAMESPACES)
    for scan, _ in simulate(tutorial_scene(), 1.0, seed=1):
        harness.send(ros_scan(scan))
    assert {m.ns for arr in harness.markers for m in arr.markers} == set(MARKER_NAMESPACES)


def test_reset_service_drops_the_tracks_and_their_markers(harness):
    from std_srvs.srv import Trigger

    data = simulate(tutorial_scene(), 4.0, seed=1)
    for scan, _ in data[:20]:
        harness.send(ros_scan(scan))
    before = {o.id for o in harness.tracks[-1].objects}
    assert before
    client = harness.probe.create_client(Trigger, '/extended_tracker/reset')
    harness.spin_until(client.service_is_ready)
    future = client.call_async(Trigger.Request())
    harness.spin_until(future.done)
    assert future.done() and future.result().success
    first_new = harness.node.state.filter.next_label
    assert first_new > max(before)
    assert future.result().message.endswith(f'new ids start at {first_new}')
    out = harness.send(ros_scan(data[20][0]))
    assert len(out.objects) == 0                          # tracks gone at once
    deleted = {x.id for x in harness.markers[-1].markers if x.action == 2 and x.ns == 'outline'}
    assert deleted == before                              # and their outlines deleted
    for scan, _ in data[21:]:
        out = harness.send(ros_scan(scan))
    ids = {o.id for o in out.objects}
    assert ids and min(ids) >= first_new                  # the objects again, new ids
    client.destroy()



def zero_increment(scan):
    """A copy of ``scan`` as a LaserScan with angle_increment 0: a malformed scan."""
    bad = copy.deepcopy(ros_scan(scan))
    bad.angle_increment = 0.0
    return bad

def test_robustness_every_case_counted_never_a_crash(harness):
    data = simulate(tutorial_scene(), 2.0, seed=0)
    scans = [ros_scan(s) for s, _ in data]
    for s in scans[:10]:
        harness.send(s)
    bad = zero_increment(scans[10])                       # malformed
    out = harness.send(bad)
    assert len(out.objects) == len(harness.tracks[-2].objects)   # estimates kept
    short = copy.deepcopy(scans[11])
    short.ranges = short.ranges[:10]                      # len(ranges) inconsistent
    harness.send(short)
    other = copy.deepcopy(scans[12])
    other.header.frame_id = 'rear_laser'                  # a second frame
    out = harness.send(other)
    assert out.header.frame_id == 'laser'
    harness.send(scans[12])
    harness.send(scans[3])                                # stamp goes backwards
    gap = copy.deepcopy(scans[13])
    gap.header.stamp.sec += 100                           # huge gap
    harness.send(gap)
    nan = copy.deepcopy(scans[14])
    nan.header.stamp.sec += 100
    nan.ranges = [float('nan')] * len(nan.ranges)          # all invalid: predict only
    harness.send(nan)
    c = harness.node.counts
    assert c.get('malformed_scan') == 2 and c.get('foreign_frame') == 1
    assert c.get('time_backwards') == 1 and c.get('time_gap') == 1
    assert 'internal_error' not in c
    # every scan got its publication, valid or not
    assert len(harness.tracks) == harness.node.scans == 17      # 10 good + 7 special


def test_diagnostics_give_each_scan_its_figures_and_the_event_counts(harness):
    """One DiagnosticArray per scan, with the scan's stamp and frame: OK and 'ok' for a
    plain scan, WARN and the event's name for a special one; the per-scan figures, and
    the running count of each event."""
    from diagnostic_msgs.msg import DiagnosticStatus

    data = simulate(tutorial_scene(), 1.5, seed=0)
    for scan, _ in data[:12]:
        reply = harness.send(ros_scan(scan))
    d = harness.diagnostics[-1]
    assert d.header == reply.header and len(harness.diagnostics) == 12
    st = d.status[0]
    values = {kv.key: kv.value for kv in st.values}
    assert st.level == DiagnosticStatus.OK and st.message == 'ok'
    assert st.name == 'extended_tracker: tracker' and st.hardware_id == 'laser'
    assert int(values['objects']) == len(reply.objects) >= 2
    assert int(values['scans']) == 12 and int(values['beams']) == 361
    assert int(values['detections']) == int(np.isfinite(data[11][0].ranges).sum())
    assert float(values['processing_time_ms']) == round(reply.processing_time * 1e3, 3) > 0
    # the clutter rate the filter assumes: the told one, or more where it learned more
    learned = harness.node.state.filter.clutter_rate
    assert learned is not None
    assert float(values['clutter_rate']) == round(max(1.0, learned), 2)
    assert not [k for k in values if k.startswith('count_')]
    bad = zero_increment(data[12][0])
    for _ in range(2):
        harness.send(bad)
    st = harness.diagnostics[-1].status[0]
    values = {kv.key: kv.value for kv in st.values}
    assert st.level == DiagnosticStatus.WARN and st.message == 'malformed_scan'
    assert values['count_malformed_scan'] == '2' and values['scans'] == '14'
    harness.send(ros_scan(data[13][0]))
    st = harness.diagnostics[-1].status[0]
    assert st.level == DiagnosticStatus.OK
    assert {kv.key: kv.value for kv in st.values}['count_malformed_scan'] == '2'


def fail_on_call(monkeypatch, module, name, n, error):
    """``module.name`` raises ``error`` on its ``n``-th call; the others go through."""
    real = getattr(module, name)
    calls = {'n': 0}

    def failing_once(*args, **kwargs):
        calls['n'] += 1
        if calls['n'] == n:
            raise error
        return real(*args, **kwargs)

    monkeypatch.setattr(module, name, failing_once)


def test_a_pipeline_failure_is_answered_counted_and_survived(harness, monkeypatch):
    """A bug that makes step raise on one scan: the node stays up, publishes the previous
    estimates for that scan (its stamp, the tracked frame), with diagnostics at ERROR,
    logs and counts it, and carries on with the next scan from the unchanged state."""
    from diagnostic_msgs.msg import DiagnosticStatus

    import extended_tracker.pipeline as pipeline_mod

    fail_on_call(monkeypatch, pipeline_mod, 'step', 15, RuntimeError('a bug'))
    data = simulate(tutorial_scene(), 2.0, seed=0)
    replies = [harness.send(ros_scan(scan)) for scan, _ in data]
    assert len(replies) == harness.node.scans == 20
    before, failed, after = replies[13], replies[14], replies[15]
    assert [o.id for o in failed.objects] == [o.id for o in before.objects] != []
    assert [o.position.x for o in failed.objects] == [o.position.x for o in before.objects]
    assert failed.header.stamp == ros_scan(data[14][0]).header.stamp
    assert failed.header.frame_id == 'laser'
    st = harness.diagnostics[14].status[0]
    assert st.level == DiagnosticStatus.ERROR and st.message == 'internal_error'
    assert harness.node.counts == {'internal_error': 1}
    assert harness.diagnostics[15].status[0].level == DiagnosticStatus.OK
    assert {o.id for o in after.objects} == {o.id for o in before.objects}


def test_a_failure_to_build_the_messages_is_counted_and_survived(harness, monkeypatch):
    """A bug in building one scan's markers: out of the callback, the exception would end
    spin and the node with it. It is logged and counted; that scan's diagnostics still
    go out, and the next scan is answered in full."""
    import extended_tracker.ros.node as node_mod

    fail_on_call(monkeypatch, node_mod, 'markers_data', 3, ValueError('a bug'))
    data = simulate(tutorial_scene(), 0.5, seed=0)
    for scan, _ in data[:2]:
        harness.send(ros_scan(scan))
    harness.expect_markers = False                        # the third gets none
    harness.send(ros_scan(data[2][0]))
    assert len(harness.markers) == 2 and len(harness.diagnostics) == 3
    assert harness.node.counts == {'internal_error': 1}
    harness.expect_markers = True
    for scan, _ in data[3:]:
        harness.send(ros_scan(scan))
    assert len(harness.markers) == len(harness.tracks) - 1 == 4


@pytest.mark.slow
def test_a_node_that_cannot_keep_up_says_so(harness, monkeypatch):
    """Scans 0.1 s apart, each taking 0.12 s: after ten in a row the node logs and counts
    falling_behind (in the diagnostics too), and again after ten more; at its normal pace
    it never does."""
    import extended_tracker.pipeline as node_mod

    data = simulate(tutorial_scene(), 4.0, seed=0)
    for scan, _ in data[:5]:
        harness.send(ros_scan(scan))
    assert harness.node.counts == {}
    real_step = node_mod.step

    def slow(*args, **kwargs):
        time.sleep(0.12)
        return real_step(*args, **kwargs)

    monkeypatch.setattr(node_mod, 'step', slow)
    for scan, _ in data[5:14]:
        harness.send(ros_scan(scan))
    assert harness.node.counts == {}                  # nine slow scans
    harness.send(ros_scan(data[14][0]))
    assert harness.node.counts == {'falling_behind': 1}
    values = {kv.key: kv.value for kv in harness.diagnostics[-1].status[0].values}
    assert values['count_falling_behind'] == '1'
    # the run starts again: ten more slow scans in a row are the second time
    for scan, _ in data[15:24]:
        harness.send(ros_scan(scan))
    assert harness.node.counts == {'falling_behind': 1}
    harness.send(ros_scan(data[24][0]))
    assert harness.node.counts == {'falling_behind': 2}
    monkeypatch.setattr(node_mod, 'step', real_step)
    for scan, _ in data[25:]:
        harness.send(ros_scan(scan))
    assert harness.node.counts == {'falling_behind': 2}


def test_only_slow_scans_in_a_row_are_falling_behind(harness):
    """The count of slow scans starts again at a scan that kept up, and at a stamp that
    goes back (no period to compare with): nine slow, one in time, nine slow is no event,
    nor are nine slow, a stamp 0.1 s back taking 0.5 s, and nine slow; a tenth in a row is."""
    node = harness.node
    t, period = 10**18, 100_000_000                         # ns: 10 Hz

    def scans(n, took):
        nonlocal t
        for _ in range(n):
            t += period
            node.check_pace(t, took)

    scans(9, 0.12)
    scans(1, 0.05)
    scans(9, 0.12)
    t -= 2 * period                                         # a stamp 0.1 s before the last
    scans(1, 0.5)
    scans(9, 0.12)
    assert node.counts == {}
    scans(1, 0.12)
    assert node.counts == {'falling_behind': 1}


def test_a_parameter_of_the_wrong_type_is_named_once_in_its_error():
    """The start-up error for a whole number given to a double: the name, the fix, and
    rclpy's reason without the name it appends again."""
    with pytest.raises(ConfigError) as err:
        NodeHarness({'model.p_survival': 1})
    text = str(err.value)
    assert text.startswith('model.p_survival must be a double (a whole number needs its '
                           'decimal point: 2.0, not 2); ')
    assert text.endswith("expecting type 'DOUBLE'")


def test_a_list_parameter_set_through_the_parameter_service(harness):
    """`ros2 param set` on birth.regions: the service hands the node an array of doubles,
    which the node takes as the list its configuration holds."""
    from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    client = harness.probe.create_client(SetParameters, '/extended_tracker/set_parameters')
    assert harness.spin_until(client.service_is_ready)
    request = SetParameters.Request(parameters=[ParameterMsg(
        name='birth.regions', value=ParameterValue(
            type=ParameterType.PARAMETER_DOUBLE_ARRAY, double_array_value=[1.0, 2.0, 0.5]))])
    future = client.call_async(request)
    assert harness.spin_until(future.done)
    assert [r.successful for r in future.result().results] == [True]
    assert harness.node.cfg.birth.regions == [1.0, 2.0, 0.5]
    assert type(harness.node.cfg.birth.regions) is list


def test_a_zero_stamp_is_answered_at_the_arrival_time(harness):
    """A driver that leaves header.stamp zero: each scan is taken (and answered) at the
    node's clock when it arrived, counted as zero_stamp; none is dropped as a repeat."""
    data = simulate(tutorial_scene(), 0.5, seed=0)
    stamps = []
    for scan, _ in data:
        msg = ros_scan(scan)
        msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0
        before = time.time_ns()
        out = harness.send(msg)
        t = out.header.stamp.sec * 10**9 + out.header.stamp.nanosec
        assert before <= t <= time.time_ns()
        stamps.append(t)
    assert stamps == sorted(set(stamps))
    c = harness.node.counts
    assert c == {'zero_stamp': 5}
    assert len(harness.tracks) == harness.node.scans == 5


def test_a_scan_no_partition_explains_is_published_and_counted(harness):
    """
    model.n_max set to 1 at run time with three people in view: no partition of a scan
    is possible. Every scan is still answered, with the tracks predicted through it; the
    event is counted (logged once), and nothing is an internal error.
    """
    data = simulate(tutorial_scene(), 3.0, seed=0)
    for scan, _ in data[:20]:
        harness.send(ros_scan(scan))
    assert len(harness.tracks[-1].objects) >= 2
    res = harness.node.set_parameters([Parameter('model.n_max', value=1)])[0]
    assert res.successful
    for scan, _ in data[20:25]:
        out = harness.send(ros_scan(scan))
        assert len(out.objects) == 1                  # at most N_max reported, never none
    c = harness.node.counts
    assert c.get('unexplained_scan') == 5 and 'internal_error' not in c
    assert len(harness.tracks) == harness.node.scans == 25


def test_parameters_from_the_yaml_file_and_descriptors():
    h = NodeHarness(args=['--ros-args', '--params-file', str(YAML)])
    try:
        assert h.node.cfg == TrackerConfig()
        names = {p for p in h.node.list_parameters([], 0).names if '.' in p}
        assert names == set(to_flat(TrackerConfig()))
        d = h.node.describe_parameters(['model.rho'])[0]
        assert 'rho X + R' in d.description
        assert d.floating_point_range[0].to_value == 4.0
        mode, n_max = h.node.describe_parameters(['model.mode', 'model.n_max'])
        assert mode.description.endswith('; one of cphd, phd')
        assert not mode.integer_range and not mode.floating_point_range
        assert n_max.description.endswith('[objects]')
        assert (n_max.integer_range[0].from_value, n_max.integer_range[0].to_value) == (1, 200)
    finally:
        h.close()


def test_changed_yaml_is_loaded(tmp_path):
    data = yaml.safe_load(YAML.read_text())
    data['/**']['ros__parameters']['model']['mode'] = 'phd'
    data['/**']['ros__parameters']['partition']['d_max'] = 1.2
    path = tmp_path / 'p.yaml'
    path.write_text(yaml.safe_dump(data))
    h = NodeHarness(args=['--ros-args', '--params-file', str(path)])
    try:
        assert h.node.cfg.model.mode == 'phd' and h.node.cfg.partition.d_max == 1.2
    finally:
        h.close()


ROBOT_PARAMS = {
    # a robot-wide parameter file: another node first, every node's common settings, then
    # the tracker's own entry in dotted names, overriding one of them
    'root': """
laser_driver:
  ros__parameters:
    frame_id: laser
    model: {mode: none}
/**:
  ros__parameters:
    use_sim_time: false
    qos_overrides:
      /scan:
        subscription:
          depth: 5
    model:
      mode: phd
      n_max: 30
extended_tracker:
  ros__parameters:
    model.n_max: 25
    partition:
      d_max: 2.5
""",
    # one robot's namespace, nested, beside another robot's tracker
    'robot1': """
robot1:
  extended_tracker:
    ros__parameters:
      model:
        mode: phd
      partition.d_min: 0.2
/robot1/laser_driver:
  ros__parameters:
    range_max: 30.0
""",
    # scalars as rcl reads them: exponents without a decimal point are doubles (strtod),
    # y and n booleans
    'scalars': """
/**:
  ros__parameters:
    background: {enabled: n}
    partition.sub_partition: N
    reduction:
      prune_weight: 1e-5
      fuse_weight: 2E+0
    model.clutter_rate: 1.5e1
    birth.regions: [1e0, -2.5, 3e-1, 5.e0, -2.5E0, .5e1]
""",
    # a section and the node's entry written twice: rcl merges them, the later value of a
    # parameter over the earlier one
    'repeated': """
/**:
  ros__parameters:
    model:
      mode: phd
      n_max: 30
    model:
      n_max: 25
/**:
  ros__parameters:
    partition.d_max: 2.5
""",
    # wildcards: /* for a node in the root namespace; an entry with no parameters ({}:
    # an empty ros__parameters is refused, below)
    'star': """
/*:
  ros__parameters:
    model: {mode: phd}
extended_tracker:
  ros__parameters: {}
""",
    # a namespace written into the key, beside a wildcard one for the node in any
    # namespace: one namespace, not two
    'robot1_keys': """
/**/extended_tracker:
  ros__parameters:
    model: {mode: phd}
/robot1/extended_tracker:
  ros__parameters:
    partition.d_max: 2.5
""",
}


# the node's namespace for the files written for one (the others run in the root)
PARAMS_NAMESPACE = {'robot1': '/robot1', 'robot1_keys': '/robot1'}


def node_reading(path, namespace=None):
    """The configuration and the unknown parameters of the node itself started with the
    parameter file ``path`` (in ``namespace``, when given): the oracle of the offline
    tools' reading."""
    args = ['--ros-args', '--params-file', str(path)]
    if namespace:
        args += ['-r', f'__ns:={namespace}']
    with NodeHarness(args=args) as h:
        return h.node.cfg, h.node.unknown_parameters


@pytest.mark.parametrize('case', sorted(ROBOT_PARAMS))
def test_offline_tools_read_a_node_parameter_file_as_the_node_does(tmp_path, case):
    """`replay --config` on the node's parameter file: the node itself, started with it
    (in the namespace the file is written for), is the oracle."""
    path = tmp_path / 'robot.yaml'
    path.write_text(ROBOT_PARAMS[case])
    from_node, _ = node_reading(path, PARAMS_NAMESPACE.get(case))
    assert from_node != TrackerConfig()                  # the file did change something
    assert load_yaml(path) == from_node


@pytest.mark.parametrize('entry', ['laser_driver:\n  ros__parameters:\n',
                                   'laser_driver:\n  ros__parameters: 3\n',
                                   'extended_tracker:\n  ros__parameters:\n'])
def test_an_entry_that_is_not_a_mapping_is_refused_as_the_node_refuses_it(tmp_path, entry):
    """rcl refuses the whole file over any node's ros__parameters that is not a mapping,
    an empty one too ({} is none): the offline tools refuse it, naming the entry, rather
    than replay with a file the node would not start with."""
    path = tmp_path / 'robot.yaml'
    path.write_text(entry + '/**:\n  ros__parameters:\n    model: {mode: phd}\n')
    with pytest.raises(Exception, match='Cannot have a value before ros__parameters'):
        NodeHarness(args=['--ros-args', '--params-file', str(path)])
    with pytest.raises(ConfigError, match=f'{entry.split(":")[0]} in {path}: ros__parameters '
                                          'must be a mapping'):
        load_yaml(path)


@pytest.mark.parametrize('text', ['', '# no parameters yet\n'])
def test_an_empty_parameter_file_gives_the_defaults_as_the_node_takes_it(tmp_path, text):
    """A parameter file with nothing in it (or comments only): the node starts with its
    defaults, and so do the offline tools, rather than refuse a file that is not a
    mapping."""
    path = tmp_path / 'empty.yaml'
    path.write_text(text)
    assert node_reading(path) == (TrackerConfig(), [])
    assert load_yaml(path) == TrackerConfig()


def test_a_section_repeated_as_a_scalar_is_an_unknown_parameter_node_and_offline(tmp_path):
    """A section written again as a plain value: rcl keeps the section's parameters and
    gives the node the value as a parameter named after the section, which it does not
    have (named once, ignored); the offline tools, which refuse unknown names, refuse it
    with its name rather than fail merging a mapping with a number."""
    path = tmp_path / 'robot.yaml'
    path.write_text('/**:\n  ros__parameters:\n    model:\n      mode: phd\n    model: 3\n')
    from_node, unknown = node_reading(path)
    assert from_node.model.mode == 'phd' and unknown == ['model']
    with pytest.raises(ConfigError, match="parameter 'model' is not of the form section.key"):
        load_yaml(path)


def test_a_parameter_file_without_the_tracker_or_with_several_is_refused(tmp_path):
    path = tmp_path / 'other.yaml'
    path.write_text('laser_driver:\n  ros__parameters:\n    frame_id: laser\n')
    with pytest.raises(ConfigError, match='no parameters for the extended_tracker node '
                                          r'\(its entries: laser_driver\)'):
        load_yaml(path)
    # two robots' trackers: which one a replay stands for, only the user knows
    path.write_text(ROBOT_PARAMS['robot1'] + ROBOT_PARAMS['robot1'].replace('robot1', 'robot2')
                    + '/**:\n  ros__parameters:\n    model:\n      n_max: 30\n')
    with pytest.raises(ConfigError, match=r'several namespaces \(/robot1, /robot2\)'):
        load_yaml(path)


def test_invalid_values_are_refused_with_a_reason(harness):
    res = harness.node.set_parameters([Parameter('model.rho', value=-1.0)])[0]
    assert not res.successful and res.reason
    res = harness.node.set_parameters([Parameter('model.mode', value='kalman')])[0]
    assert not res.successful and 'cphd' in res.reason
    res = harness.node.set_parameters([Parameter('partition.d_min', value=5.0)])[0]
    assert not res.successful and 'd_min' in res.reason
    res = harness.node.set_parameters([Parameter('model.mode', value='phd')])[0]
    assert res.successful and harness.node.cfg.model.mode == 'phd'
    # rclpy's own parameters pass through the check untouched
    before = harness.node.cfg
    res = harness.node.set_parameters([Parameter('use_sim_time', value=True)])[0]
    assert res.successful and harness.node.cfg == before
    assert harness.node.get_parameter('use_sim_time').value is True


def test_unknown_parameters_are_named_once_with_the_nearest_known_one():
    """rclpy ignores parameters a node never declares: a misspelt one in a parameter file
    would leave its default in force. The node names them once at start-up (counted in
    its diagnostics) and runs on with the rest."""
    h = NodeHarness({'birth.position_std': 0.5, 'background.enabled': False},
                    args=['--ros-args', '-p', 'model.clutter_rte:=2.0'])
    try:
        assert h.node.unknown_parameters == ['birth.position_std', 'model.clutter_rte']
        assert h.node.counts == {'unknown_parameter': 1}
        assert h.node.cfg.background.enabled is False          # the known ones apply
        reply = h.send(ros_scan(simulate(tutorial_scene(), 0.1, seed=1)[0][0]))
        assert reply is not None
    finally:
        h.close()
    h = NodeHarness(NO_BACKGROUND)
    try:
        assert h.node.unknown_parameters == [] and h.node.counts == {}
    finally:
        h.close()


def test_yaml_descriptors_and_dataclass_agree():
    assert load_yaml(YAML) == TrackerConfig()
    assert YAML.read_text() == default_yaml(), 'config/tracker.yaml is stale: make config'
    desc = parameter_descriptors()
    assert set(desc) == set(to_flat(TrackerConfig()))
    for name, (default, d) in desc.items():
        assert d.description, name
    nested = yaml.safe_load(YAML.read_text())['/**']['ros__parameters']
    assert nested == to_dict(TrackerConfig())


@pytest.mark.slow
def test_node_and_replay_publish_the_same(tmp_path):
    from rosbags.rosbag2 import Reader

    from extended_tracker.bag.bagio import message_typestore
    from extended_tracker.bag.replay import replay

    bag = tmp_path / 'scans'
    write_sim_bag(bag, 'tutorial', seed=3, duration=3.0)
    cfg = from_dict({'background': {'enabled': False}})
    replay(bag, tmp_path / 'out', cfg, progress=False)
    store = message_typestore()
    from_bag = {'/scan': [], '/tracks': [], '/tracks/markers': []}
    with Reader(tmp_path / 'out') as reader:
        for conn, _, raw in reader.messages():
            from_bag[conn.topic].append(to_plain(store.deserialize_cdr(raw, conn.msgtype)))
    h = NodeHarness(NO_BACKGROUND)
    try:
        for scan, _ in simulate(tutorial_scene(), 3.0, seed=3):
            h.send(ros_scan(scan))
        sent = [to_plain(ros_scan(scan)) for scan, _ in simulate(tutorial_scene(), 3.0, seed=3)]
        live_tracks = [to_plain(m) for m in h.tracks]
        live_markers = [to_plain(m) for m in h.markers]
    finally:
        h.close()
    assert len(live_tracks) == len(from_bag['/tracks']) == 30

    def strip(d):
        d = dict(d)
        d.pop('processing_time')
        return d

    for a, b in zip(live_tracks, from_bag['/tracks']):
        assert strip(a) == strip(b)
    assert live_markers == from_bag['/tracks/markers']
    # the bag's /scan is what the node was sent, as float32 on the wire (ranges compared
    # as arrays: some are NaN)
    assert len(from_bag['/scan']) == len(sent) == 30
    for a, b in zip(from_bag['/scan'], sent):
        assert a.keys() == b.keys() and a['header'] == b['header']
        for name in set(a) - {'header'}:
            np.testing.assert_array_equal(np.float32(a[name]), np.float32(b[name]), name)


def _node_exe():
    import sys

    return str(Path(sys.prefix) / 'lib' / 'extended_tracker' / 'tracker_node')


def _node_until_it_ends(*ros_args, ros=True):
    """Run the installed node with ``--ros-args ...`` (with ``ros=False``: with the
    arguments as given) to its end (a refused start)."""
    import os
    import subprocess

    argv = ['--ros-args', *ros_args] if ros else list(ros_args)
    return subprocess.run([_node_exe(), *argv], capture_output=True, text=True, timeout=30,
                          env=dict(os.environ))


@pytest.mark.slow
@pytest.mark.parametrize('flag', ['--help', '-h'])
def test_node_help_prints_its_usage_without_starting(flag):
    done = _node_until_it_ends(flag, ros=False)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith('usage: tracker_node [--ros-args')
    for name in ('scan (sensor_msgs/LaserScan)', 'tracks/markers', 'tracks/diagnostics',
                 '~/reset', 'config/tracker.yaml'):
        assert name in done.stdout, name
    assert 'tracking' not in done.stderr                  # no node was made


@pytest.mark.parametrize('argv, why', [
    # an option given without --ros-args: rclpy ignored it and the node ran on defaults
    (['-p', 'model.mode:=phd'], "unexpected arguments '-p model.mode:=phd': node options "
                                'go after --ros-args'),
    (['--ros-args', '--params-file', '/no/such/params.yaml'],
     "Couldn't parse params file: '--params-file /no/such/params.yaml'"),
    (['--ros-args', '-r', 'scan'], "Couldn't parse remap rule: '-r scan'"),
])
@pytest.mark.slow
def test_a_command_line_rcl_refuses_is_one_fatal_line(argv, why):
    """rcl's reason for refusing the ROS arguments was a traceback from rclpy.init with
    status 1."""
    done = _node_until_it_ends(*argv, ros=False)
    assert done.returncode == 2, done.stderr
    assert 'Traceback' not in done.stderr and why in done.stderr, done.stderr
    if argv[0] == '--ros-args':
        assert 'cannot start: ' in done.stderr
    fatal = [line for line in done.stderr.splitlines() if '[FATAL]' in line]
    assert len(fatal) == 1 and why in fatal[0]


@pytest.mark.slow
@pytest.mark.parametrize('blocked', [False, True], ids=['', 'started-blocked'])
@pytest.mark.parametrize('sig', ['SIGTERM', 'SIGINT'])
def test_process_shuts_down_cleanly(sig, blocked):
    """Also when its parent started it with the stop signals blocked (the mask is
    inherited across exec): the node unblocks what it handles; it ran on until SIGKILL."""
    import os
    import signal
    import subprocess

    from blocked import stops_blocked

    argv = [_node_exe(), '--ros-args', '-r', 'scan:=/front/scan']
    proc = subprocess.Popen(stops_blocked(argv) if blocked else argv,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            env=dict(os.environ))
    try:
        deadline = time.monotonic() + 20
        line = ''
        while 'tracking' not in line and time.monotonic() < deadline:
            line = proc.stdout.readline()
        assert '/front/scan' in line, line
        proc.send_signal(getattr(signal, sig))
        assert proc.wait(timeout=20) == 0
        # its last word: what it handled, and nothing failing on the way out
        rest = proc.stdout.read()
        assert 'stopping after 0 scans; events: none' in rest, rest
        assert 'Failed' not in rest and 'Traceback' not in rest, rest
    finally:
        if proc.poll() is None:
            proc.kill()


def test_a_stop_asked_for_while_starting_ends_quietly(monkeypatch):
    """The executable takes SIGINT/SIGTERM before its heavy imports: a signal then only
    sets the stop, the node is never started, the process ends with status 0 (not a
    KeyboardInterrupt traceback from an import, or a kill by SIGTERM), and the handlers
    and signal mask it found are back afterwards."""
    import os
    import signal

    import rclpy

    import extended_tracker.ros.entry as entry
    import extended_tracker.ros.node as node_mod
    from extended_tracker.stopping import STOP_SIGNALS

    before = {sig: signal.getsignal(sig) for sig in STOP_SIGNALS}
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    inits = []
    monkeypatch.setattr(rclpy, 'init', lambda *a, **k: inits.append(1))
    real_main = node_mod.main

    for sig in STOP_SIGNALS:
        def slow_start(args=None, stop=None, sig=sig):
            os.kill(os.getpid(), sig)             # arrives while the node is loading
            assert stop.wait(5)
            return real_main(args, stop=stop)

        monkeypatch.setattr(node_mod, 'main', slow_start)
        entry.main([])                            # returns: no exception, no exit
    assert not inits
    assert {sig: signal.getsignal(sig) for sig in STOP_SIGNALS} == before
    assert signal.pthread_sigmask(signal.SIG_BLOCK, []) == mask


@pytest.mark.slow
def test_process_refuses_an_invalid_parameter_with_the_reason():
    done = _node_until_it_ends('-p', 'model.mode:=kalman')
    assert done.returncode == 2
    assert "model.mode must be one of ('cphd', 'phd'), got 'kalman'" in done.stderr


@pytest.mark.slow
def test_a_whole_number_for_a_double_parameter_is_one_line_in_the_node_and_offline(tmp_path):
    """rclpy types parameters strictly: `p_survival: 1` (no decimal point) for a double
    stopped the node with a traceback from its constructor. It is now the one-line
    invalid-configuration error with the fix, status 2, on the command line and in a
    parameter file alike; the offline tools refuse the same parameter file the same way
    (so a file a replay accepts also starts the node), and plain config sections still
    take a whole number."""
    node = _node_until_it_ends
    params = tmp_path / 'params.yaml'
    params.write_text('extended_tracker:\n  ros__parameters:\n    model:\n'
                      '      p_survival: 1\n')
    for done in (node('-p', 'model.p_survival:=1'), node('--params-file', str(params))):
        assert done.returncode == 2 and 'Traceback' not in done.stderr, done.stderr
        assert ('invalid configuration: model.p_survival must be a double (a whole number '
                'needs its decimal point: 2.0, not 2)') in done.stderr
    done = node('-p', 'birth.regions:=[1, 2, 0]')
    assert done.returncode == 2 and 'Traceback' not in done.stderr, done.stderr
    assert 'birth.regions must be a list of doubles (whole numbers need their decimal ' \
           'points' in done.stderr
    done = node('-p', 'model.n_max:=40.0')
    assert done.returncode == 2 and 'model.n_max must be an integer;' in done.stderr
    with pytest.raises(ConfigError, match=r'model.p_survival in .*params.yaml must be a '
                                          r'double \(a whole number needs its decimal '
                                          r'point: 1.0, not 1\)'):
        load_yaml(params)
    params.write_text('/**:\n  ros__parameters:\n    birth:\n      regions: [1, 2, 0]\n')
    with pytest.raises(ConfigError, match='birth.regions in .* must be a list of doubles'):
        load_yaml(params)
    plain = tmp_path / 'plain.yaml'
    plain.write_text('model:\n  p_survival: 1\nbirth:\n  regions: [1, 2, 0]\n')
    assert load_yaml(plain).model.p_survival == 1 and load_yaml(plain).birth.regions == [
        1, 2, 0]
    # a bool for a double is no whole number missing its point: it is refused as a bool
    params.write_text('/**:\n  ros__parameters:\n    model:\n      p_survival: true\n')
    with pytest.raises(ConfigError, match='model.p_survival must be a number, got True'):
        load_yaml(params)


def test_node_overhead_bench_with_and_without_a_marker_listener(marker_builds):
    """The bench's node figure: with a listener the callback builds markers, without it
    not; both report a callback time over the step's."""
    from extended_tracker.ros.bench_node import node_overhead

    for listener in (True, False):
        marker_builds.clear()
        r = node_overhead(scans=25, marker_listener=listener)
        assert r['callback_median_ms'] > r['step_median_ms'] > 0
        assert len(marker_builds) == (25 if listener else 0)


def test_node_overhead_figures_by_hand():
    """The node figure's arithmetic on callbacks timed by hand: the warm-up callbacks
    left out, the overhead the median of each callback's own (0.5 ms here, where the
    difference of the medians would say 0.1), the p99 between the two slowest callbacks
    (2 + 0.98 x 8 ms)."""
    from extended_tracker.ros.bench_node import overhead_figures

    total = [0.100, 0.100, 0.001, 0.002, 0.010]
    inner = [0.090, 0.090, 0.0005, 0.0019, 0.002]
    r = overhead_figures(total, inner, warm=2)
    assert r == pytest.approx({'callback_median_ms': 2.0, 'step_median_ms': 1.9,
                               'overhead_median_ms': 0.5, 'callback_p99_ms': 9.84})


def test_the_readme_harness_example_runs(capsys):
    """The README's launch-free example, as printed there, against the installed node."""
    text = (ROOT / 'README.md').read_text()
    block = text.split('<!-- harness-example:begin -->')[1]
    block = block.split('<!-- harness-example:end -->')[0]
    code = block.split('```python\n')[1].split('```')[0]
    exec(compile(code, 'README.md harness example', 'exec'), {})
    first, second = capsys.readouterr().out.splitlines()
    count, ids = first.split(' objects, ids ')
    assert int(count) >= 3 and len(eval(ids)) == int(count)
    assert second == 'events: none'


def test_invalid_value_at_start_up_is_refused_and_leaves_no_context(monkeypatch):
    """An invalid parameter: the harness raises what the node raised, and shuts down the
    context it made for it."""
    import rclpy.context

    import extended_tracker.ros.testing as testing

    made = []

    class Recorded(rclpy.context.Context):
        def __init__(self):
            super().__init__()
            made.append(self)

    monkeypatch.setattr(testing, 'Context', Recorded)
    with pytest.raises(Exception, match='model.mode'):
        NodeHarness({'model.mode': 'kalman'})
    assert len(made) == 1 and not made[0].ok()
    with NodeHarness(NO_BACKGROUND, markers=False) as h:
        assert made[1].ok() and h.send(ros_scan(simulate(tutorial_scene(), 0.1, seed=1)[0][0]))
    assert not made[1].ok()


def test_the_harness_keeps_dds_on_the_machine_and_bounds_every_wait(monkeypatch):
    """A robot's test that uses the harness without this package's conftest still stays
    on loopback (the harness sets the discovery range when it is unset), and a node that
    never answers fails the send after ``spin_limit`` with a clear message instead of
    hanging."""
    import os

    monkeypatch.delenv('ROS_AUTOMATIC_DISCOVERY_RANGE')
    with NodeHarness(NO_BACKGROUND, markers=False, spin_limit=0.5) as h:
        assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
        scan = ros_scan(simulate(tutorial_scene(), 0.1, seed=1)[0][0])
        assert h.send(scan) is not None
        monkeypatch.setattr(h.node.pub_tracks, 'publish', lambda msg: None)
        with pytest.raises(AssertionError, match=r'no reply from the node within 0.5 s'):
            h.send(scan)
        # a wait of its own length: a condition never met returns false after it, not
        # after the harness's spin_limit
        h.spin_limit = 60.0
        t0 = time.monotonic()
        assert h.spin_until(lambda: False, limit=0.2) is False
        assert time.monotonic() - t0 < 30.0


def test_every_event_is_explained_in_the_readme():
    """The README's list of events names each one the pipeline and the node can raise,
    and no other."""
    import re

    from extended_tracker.pipeline import EVENTS
    from extended_tracker.ros.node import NODE_EVENTS

    text = (ROOT / 'README.md').read_text()
    block = text.split('- **Events**')[1].split('\n- **')[0]
    listed = set(re.findall(r'^  - `(\w+)`(?:, `(\w+)`)?', block, re.M))
    names = {n for pair in listed for n in pair if n}
    assert names == set(EVENTS) | set(NODE_EVENTS)


def test_shutdown_after_a_signal_already_shut_the_context(monkeypatch):
    """The race the SIGINT test met 2 times in 40: the signal handler's thread shuts the
    context down between try_shutdown's check and its shutdown, which then raises. Not an
    error once the context is down; still one while it is up."""
    import rclpy

    import extended_tracker.ros.node as node_mod

    def raced():
        raise RuntimeError('failed to shutdown: rcl_shutdown already called')

    monkeypatch.setattr(rclpy, 'try_shutdown', raced)
    monkeypatch.setattr(rclpy, 'ok', lambda *a, **k: False)
    node_mod.shutdown_context()                                   # the signal's shutdown stands
    monkeypatch.setattr(rclpy, 'ok', lambda *a, **k: True)
    with pytest.raises(RuntimeError, match='already called'):
        node_mod.shutdown_context()


class RecordingLogger:
    """Stands in for the node's logger: each call as (level, text, keyword arguments)."""

    def __init__(self):
        self.lines = []

    def __getattr__(self, level):
        def log(text, **kwargs):
            self.lines.append((level, text, kwargs))
            return True
        return log

    def at(self, level):
        return [(text, kwargs) for lev, text, kwargs in self.lines if lev == level]


def test_an_event_is_logged_once_a_kind_of_reason_then_summarised_and_a_bug_at_error(
        harness, monkeypatch):
    """The first of a kind in full; another kind of reason of the same event at once, not
    lost in a 10 s window; the rest counted and said by the periodic summary, whenever it
    comes, with its last reason (a malformed scan's reason is also in the diagnostics); a
    failure to publish, a bug, at ERROR."""
    import extended_tracker.ros.node as node_mod

    rec = RecordingLogger()
    monkeypatch.setattr(harness.node, 'get_logger', lambda: rec)
    data = simulate(tutorial_scene(), 0.5, seed=0)
    bad = zero_increment(data[0][0])
    short = copy.deepcopy(ros_scan(data[1][0]))
    short.ranges = short.ranges[:-10]                        # a truncated scan
    for scan in (bad, bad, short, bad):
        harness.send(scan)
    (first, _), (second, _) = rec.at('warning')
    assert first == ('malformed_scan: angle_increment must not be zero (counted; further '
                     'ones are summarised every 10 s)')
    assert second.startswith('malformed_scan: len(ranges) = ') and second.endswith(
        '(3 so far)')
    status = harness.diagnostics[-1].status[0]
    values = {kv.key: kv.value for kv in status.values}
    assert status.message == 'malformed_scan'
    assert values['reason'] == values['last_reason_malformed_scan'] == (
        'angle_increment must not be zero')
    assert values['count_malformed_scan'] == '4'
    harness.node.log_summary()
    (summary, _), = rec.at('warning')[2:]
    assert summary == ('malformed_scan: 2 more since the last summary (4 in all); last: '
                       'angle_increment must not be zero')
    harness.node.log_summary()                               # nothing new: nothing said
    assert len(rec.at('warning')) == 3 and rec.at('error') == []
    fail_on_call(monkeypatch, node_mod, 'markers_data', 1, ValueError('a bug'))
    harness.expect_markers = False                        # that scan gets none
    harness.send(ros_scan(data[1][0]))
    (text, _), = rec.at('error')
    assert text.startswith("internal_error: publishing the estimates failed: ValueError('a bug')")


def test_the_summary_runs_on_a_steady_timer_every_ten_seconds(harness):
    """What is counted and not logged is said every SUMMARY_PERIOD_S by a timer on the
    steady clock, not only when a later event of the same kind happens to come."""
    from rclpy.clock import ClockType

    import extended_tracker.ros.node as node_mod

    timer = harness.node.summary_timer
    assert node_mod.SUMMARY_PERIOD_S == 10.0 and timer.timer_period_ns == 10 * 10**9
    assert timer.clock.clock_type == ClockType.STEADY_TIME
    assert timer.callback == harness.node.log_summary


def test_scans_missing_between_stamps_are_counted_and_said(harness, monkeypatch):
    """Scans that never reach the callback (the subscription queue dropped them in a
    burst, or the driver did): a step of k scan periods between stamps is k - 1 scans
    missing, event scans_dropped, and the total in the diagnostics."""
    rec = RecordingLogger()
    monkeypatch.setattr(harness.node, 'get_logger', lambda: rec)
    data = [s for s, _ in simulate(tutorial_scene(), 2.0, seed=0)]
    for scan in data[:10] + data[13:15]:                  # three missing, then on
        harness.send(ros_scan(scan))
    assert harness.node.counts.get('scans_dropped') == 1
    (text, _), = rec.at('warning')
    assert text.startswith('scans_dropped: 3 scan(s) missing before the one stamped ')
    values = {kv.key: kv.value for kv in harness.diagnostics[-1].status[0].values}
    assert values['scans_dropped'] == '3' and values['count_scans_dropped'] == '1'


def test_get_parameters_answers_for_every_name_with_the_list_among_them(harness):
    """GetParameters for birth.regions (a list of doubles with no default) with other
    names: rclpy's service answered nothing at all while the list was uninitialised."""
    from rcl_interfaces.srv import GetParameters

    client = harness.probe.create_client(GetParameters, '/extended_tracker/get_parameters')
    assert harness.spin_until(client.service_is_ready)
    future = client.call_async(GetParameters.Request(names=['birth.regions', 'model.n_max']))
    assert harness.spin_until(future.done)
    regions, n_max = future.result().values
    assert list(regions.double_array_value) == [] and n_max.integer_value == 40


def test_a_value_out_of_its_range_at_start_up_is_one_clear_error():
    """-p model.n_max:=1000 or p_survival 1.5 (or such a value in a parameter file): the
    node refuses in one line with the range, as for a wrong type (rclpy raised its
    InvalidParameterValueException through the constructor)."""
    for arg, said in (('model.n_max:=1000', 'model.n_max = 1000 is out of its range '
                                            '[1, 200]: cardinality pmf truncated'),
                      ('model.p_survival:=1.5', 'model.p_survival = 1.5 is out of its '
                                                'range [0, 1]: probability an object')):
        with pytest.raises(ConfigError, match=re.escape(said)):
            NodeHarness(args=['--ros-args', '-p', arg])


@pytest.mark.slow
def test_the_process_refuses_an_out_of_range_value_in_one_fatal_line(tmp_path):
    params = tmp_path / 'params.yaml'
    params.write_text('extended_tracker:\n  ros__parameters:\n    model:\n'
                      '      n_max: 1000\n')
    for done in (_node_until_it_ends('-p', 'model.p_survival:=1.5'),
                 _node_until_it_ends('--params-file', str(params))):
        assert done.returncode == 2 and 'Traceback' not in done.stderr, done.stderr
        assert '[FATAL]' in done.stderr and 'is out of its range' in done.stderr


def test_a_failure_on_a_zero_stamped_scan_is_answered_at_its_arrival(harness, monkeypatch):
    """The previous estimates published for a scan the pipeline failed on carry the time
    that scan is taken at: for a zero stamp, its arrival."""
    import extended_tracker.pipeline as node_mod

    data = simulate(tutorial_scene(), 0.5, seed=0)
    for scan, _ in data[:3]:
        harness.send(ros_scan(scan))
    fail_on_call(monkeypatch, node_mod, 'step', 1, RuntimeError('a bug'))
    msg = ros_scan(data[3][0])
    msg.header.stamp.sec, msg.header.stamp.nanosec = 0, 0
    before = time.time_ns()
    out = harness.send(msg)
    assert before <= out.header.stamp.sec * 10**9 + out.header.stamp.nanosec <= time.time_ns()
    assert harness.node.counts == {'internal_error': 1}


def test_unknown_parameters_are_named_with_the_nearest_known_one(monkeypatch):
    """The start-up warning says what each unknown name was probably meant to be."""
    import extended_tracker.ros.node as node_mod

    rec = RecordingLogger()
    monkeypatch.setattr(node_mod.TrackerNode, 'get_logger', lambda self: rec)
    with NodeHarness(dict(NO_BACKGROUND, **{'model.clutter_rte': 2.0, 'zz': 1.0})):
        pass
    (text, _), = rec.at('warning')
    assert text == ('2 given parameter(s) this node does not have, ignored: '
                    'model.clutter_rte (did you mean model.clutter_rate?), zz')


def test_the_log_says_once_when_the_scans_show_legs_and_again_after_a_reset(harness,
                                                                           monkeypatch):
    """A walker at leg height: one info line names the scan from which the legs are seen
    (the partition then spans the leg gap), none for the scans after it; a reset forgets
    the decision, so the line comes again. A walker at body height: no such line."""
    from extended_tracker.sim.laser import LaserSpec, Scene, SimObject

    def walker(shape):
        scene = Scene(objects=(SimObject((3.0, -1.5), (0.0, 1.0), shape=shape),),
                      laser=LaserSpec(n_beams=513, dropout=0.0))
        return [ros_scan(scan) for scan, _ in simulate(scene, 1.5, seed=1)]

    def said():
        return [text for text, _ in rec.at('info') if text.startswith('the scans show legs')]

    rec = RecordingLogger()
    monkeypatch.setattr(harness.node, 'get_logger', lambda: rec)
    for scan in walker('ellipse'):
        harness.send(scan)
    assert said() == [] and not harness.node.state.legs.seen
    harness.node._on_reset(None, type('Response', (), {})())
    legs = walker('legs')
    for scan in legs:
        harness.send(scan)
    first, = said()
    seen_at = int(re.search(r'\(scan (\d+)\)', first).group(1))
    assert len(legs) < seen_at < 2 * len(legs)            # counted from the node's start
    assert first.endswith('(partition.leg_gap 0.45 m)')
    harness.node._on_reset(None, type('Response', (), {})())
    for scan in legs:
        harness.send(scan)
    assert len(said()) == 2
