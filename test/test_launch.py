"""
launch/tracker.launch.py, without ros2launch (not installable here): its logic runs against
small stand-ins for the launch API's constructors when the real packages are absent, and
every file and executable it names must exist in the installed layout.
"""

import importlib.util
import os
from pathlib import Path
import sys
import types

import pytest

ROOT = Path(__file__).resolve().parents[1]
LAUNCH_FILE = ROOT / 'launch' / 'tracker.launch.py'


class _Recorded:
    """Stands in for a launch action or substitution: keeps its constructor arguments."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _Config(_Recorded):
    def perform(self, context):
        return context.launch_configurations[self.args[0]]


class _Context:
    """Stands in for a LaunchContext: the launch configurations (arguments, and the
    namespace a PushRosNamespace around the include sets)."""

    def __init__(self, configurations: dict):
        self.launch_configurations = dict(configurations)


def _stand_ins():
    mods = {name: types.ModuleType(name) for name in (
        'launch', 'launch.actions', 'launch.event_handlers', 'launch.substitutions',
        'launch_ros', 'launch_ros.actions')}
    mods['launch'].LaunchDescription = _Recorded
    mods['launch.actions'].DeclareLaunchArgument = _Recorded
    mods['launch.actions'].OpaqueFunction = _Recorded
    mods['launch.actions'].RegisterEventHandler = _Recorded
    mods['launch.event_handlers'].OnShutdown = _Recorded
    mods['launch.substitutions'].LaunchConfiguration = _Config
    mods['launch_ros.actions'].Node = _Recorded
    return mods


@pytest.fixture
def launch_module(monkeypatch):
    try:
        import launch_ros  # noqa: F401

        import launch  # noqa: F401  (a real Jazzy install: nothing to stand in for)
        pytest.skip('real launch packages present: ros2 launch checks this file there')
    except ImportError:
        pass
    for name, mod in _stand_ins().items():
        monkeypatch.setitem(sys.modules, name, mod)
    if 'AMENT_PREFIX_PATH' not in os.environ:          # the venv is the install prefix
        monkeypatch.setenv('AMENT_PREFIX_PATH', sys.prefix)
    spec = importlib.util.spec_from_file_location('tracker_launch', LAUNCH_FILE)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _args(ld):
    actions = ld.args[0]
    declared = {a.args[0]: a.kwargs['default_value'] for a in actions[:-1]}
    function = actions[-1].kwargs['function']
    return declared, lambda configurations: function(_Context(configurations))


def test_node_gets_the_installed_parameters_and_the_remapped_scan(launch_module):
    from ament_index_python.packages import get_package_prefix, get_package_share_directory

    declared, make_node = _args(launch_module.generate_launch_description())
    assert declared == {'scan': 'scan', 'preset': '', 'params_file': '', 'use_sim_time': 'false',
                        'namespace': '', 'rviz': 'false', 'rviz_frame': 'odom'}
    (node,) = make_node(dict(declared, scan='/front/scan'))       # no RViz unless asked
    kw = node.kwargs
    assert kw['package'] == 'extended_tracker' and kw['name'] == 'extended_tracker'
    assert kw['namespace'] is None                             # the launch's own, if any
    exe = Path(get_package_prefix('extended_tracker')) / 'lib' / 'extended_tracker'
    assert (exe / kw['executable']).is_file()                  # where ros2 run looks
    share = Path(get_package_share_directory('extended_tracker'))
    assert kw['parameters'] == [str(share / 'config' / 'tracker.yaml'), {'use_sim_time': False}]
    assert kw['remappings'] == [('scan', '/front/scan')]


def test_a_preset_applies_after_the_base_file_and_an_unknown_one_is_refused(launch_module):
    from ament_index_python.packages import get_package_share_directory

    declared, make_node = _args(launch_module.generate_launch_description())
    share = Path(get_package_share_directory('extended_tracker'))
    (node,) = make_node(dict(declared, preset='leg_height', use_sim_time='True'))
    files = node.kwargs['parameters']
    assert files[:2] == [str(share / 'config' / 'tracker.yaml'),
                         str(share / 'config' / 'leg_height.yaml')]
    assert all(Path(f).is_file() for f in files[:2]) and files[2] == {'use_sim_time': True}
    (node,) = make_node(dict(declared, params_file='/site/my.yaml'))
    assert node.kwargs['parameters'][0] == '/site/my.yaml'
    with pytest.raises(RuntimeError, match='no preset'):
        make_node(dict(declared, preset='ceiling'))


def test_rviz_starts_on_request_with_the_scan_topic_and_fixed_frame(launch_module):
    from ament_index_python.packages import get_package_share_directory
    import yaml

    declared, make_node = _args(launch_module.generate_launch_description())
    installed = Path(get_package_share_directory('extended_tracker')) / 'rviz' / 'tracker.rviz'
    with open(installed) as f:
        original = yaml.safe_load(f)
    for scan, topic in (('/front/scan', '/front/scan'), ('scan', '/scan')):
        tracker, rviz, cleanup = make_node(dict(declared, scan=scan, rviz='True',
                                                rviz_frame='base_scan', use_sim_time='true'))
        assert tracker.kwargs['remappings'] == [('scan', scan)]
        kw = rviz.kwargs
        assert (kw['package'], kw['executable']) == ('rviz2', 'rviz2')
        assert kw['parameters'] == [{'use_sim_time': True}]
        flag, path, frame_flag, frame = kw['arguments']
        assert (flag, frame_flag, frame) == ('-d', '-f', 'base_scan')
        with open(path) as f:
            written = yaml.safe_load(f)
        # the written copy is the installed config with the scan display on the topic
        displays = written['Visualization Manager']['Displays']
        (laser,) = [d for d in displays if d['Class'] == 'rviz_default_plugins/LaserScan']
        assert laser['Topic']['Value'] == topic
        laser['Topic']['Value'] = '/scan'
        assert written == original
        # the copy's directory goes when the launch shuts down, not one left per launch
        (handler,) = cleanup.args
        assert Path(path).parent.is_dir()
        handler.kwargs['on_shutdown'](object(), {})
        assert not Path(path).parent.exists()


@pytest.mark.parametrize('pushed, given', [('', ''), ('/robot1', ''), ('robot1/left', ''),
                                           ('', 'front'), ('/robot1', 'front'),
                                           ('/robot1', '/rear')])
def test_rviz_shows_the_node_s_topics_in_its_namespace(launch_module, pushed, given):
    """With a namespace pushed around the include (PushRosNamespace), given as the
    namespace argument, or both, RViz's scan and marker displays are the topics the node
    itself resolves where it runs (the node, started in the namespace launch_ros gives
    it and with the same remapping, is the oracle)."""
    import rclpy
    from rclpy.context import Context
    import yaml

    from extended_tracker.ros.node import TrackerNode

    declared, make_node = _args(launch_module.generate_launch_description())
    # launch_ros: a relative node namespace goes inside the pushed one, an absolute one not
    where = given if given.startswith('/') else '/' + '/'.join(
        p for p in (pushed.strip('/'), given) if p)
    for scan in ('scan', '/front/scan', '~/scan', 'lidar/scan'):
        configurations = dict(declared, scan=scan, rviz='true', namespace=given)
        if pushed:
            configurations['ros_namespace'] = pushed
        tracker, rviz, cleanup = make_node(configurations)
        assert tracker.kwargs['namespace'] == rviz.kwargs['namespace'] == (given or None)
        with open(rviz.kwargs['arguments'][1]) as f:
            displays = {d['Class']: d['Topic']['Value']
                        for d in yaml.safe_load(f)['Visualization Manager']['Displays']
                        if 'Topic' in d}
        cleanup.args[0].kwargs['on_shutdown'](object(), None)
        args = ['--ros-args', '-r', f'scan:={scan}']
        if where != '/':
            args += ['-r', f'__ns:={where}']
        ctx = Context()
        rclpy.init(context=ctx, args=args)
        try:
            node = TrackerNode(context=ctx)
            want = (node.sub.topic_name, node.pub_markers.topic_name)
            node.destroy_node()
        finally:
            rclpy.try_shutdown(context=ctx)
        got = (displays['rviz_default_plugins/LaserScan'],
               displays['rviz_default_plugins/MarkerArray'])
        assert got == want, (pushed, given, scan)
