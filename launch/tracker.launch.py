"""
``ros2 launch extended_tracker tracker.launch.py [scan:=/front/scan] [preset:=leg_height]
[params_file:=/path/to/tracker.yaml] [use_sim_time:=true] [namespace:=front]
[rviz:=true [rviz_frame:=odom]]``

Starts ``tracker_node`` with the installed ``config/tracker.yaml`` (or ``params_file``),
then the preset's changes (``config/<preset>.yaml``) when one is named, and the input topic
remapped to ``scan``. ``use_sim_time`` for a bag played with ``ros2 bag play --clock``.
``rviz:=true`` also starts RViz2 with the installed ``rviz/tracker.rviz``, its scan display
on ``scan`` and its fixed frame ``rviz_frame`` (the tracks' frame, ``tf.fixed_frame``:
odom; the scan's ``frame_id`` for a scanner with no TF); that config is a copy written to a temporary directory, removed when the
launch shuts down. ``namespace`` puts the node (and RViz) in a namespace, as does
including the launch under ``PushRosNamespace`` (a relative ``namespace`` goes inside a
pushed one): one tracker per scanner, ``namespace:=front`` and ``namespace:=rear``. The
RViz displays follow: a relative ``scan`` and the node's marker topic are taken in the
node's namespace.
"""

import os
import shutil
import tempfile

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction, RegisterEventHandler
from launch.event_handlers import OnShutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from extended_tracker.configio import NODE_NAME

PACKAGE = 'extended_tracker'


def parameter_files(share: str, params_file: str, preset: str) -> list:
    """The parameter files in the order they apply: the base, then the preset's changes."""
    files = [params_file or os.path.join(share, 'config', 'tracker.yaml')]
    if preset:
        path = os.path.join(share, 'config', f'{preset}.yaml')
        if not os.path.isfile(path):
            raise RuntimeError(f'no preset {preset!r}: {path} does not exist')
        files.append(path)
    return files


MARKERS_TOPIC = 'tracks/markers'       # the node's marker topic, relative to its namespace


def resolve(name: str, namespace: str) -> str:
    """
    ``name`` as the tracker node in ``namespace`` resolves it: absolute names stay,
    relative ones go into the namespace, ``~`` is the node's own.
    """
    if name.startswith('~'):
        name = NODE_NAME + name[1:]
    if name.startswith('/'):
        return name
    ns = namespace.strip('/')
    return '/' + (ns + '/' if ns else '') + name


def node_namespace(pushed: str, given: str) -> str:
    """The namespace a node given ``given`` runs in under a pushed namespace (as
    launch_ros combines them: an absolute ``given`` stands alone)."""
    if given.startswith('/'):
        return given
    return '/' + '/'.join(p for p in (pushed.strip('/'), given.strip('/')) if p)


def rviz_config(share: str, scan_topic: str, out_dir: str, namespace: str = '') -> str:
    """
    The installed RViz config with its LaserScan display on ``scan_topic`` and its marker
    display on the node's markers, both as a node in ``namespace`` resolves them (the
    root namespace by default), written to ``out_dir``; returns its path.
    """
    import yaml

    with open(os.path.join(share, 'rviz', 'tracker.rviz')) as f:
        config = yaml.safe_load(f)
    topics = {'rviz_default_plugins/LaserScan': resolve(scan_topic, namespace),
              'rviz_default_plugins/MarkerArray': resolve(MARKERS_TOPIC, namespace)}
    for display in config['Visualization Manager']['Displays']:
        if display['Class'] in topics:
            display['Topic']['Value'] = topics[display['Class']]
    path = os.path.join(out_dir, 'extended_tracker.rviz')
    with open(path, 'w') as f:
        yaml.safe_dump(config, f, sort_keys=False)
    return path


def _remove_on_shutdown(path: str):
    """An action that deletes ``path`` (a directory this launch made) when the launch ends."""
    def remove(event, context):
        shutil.rmtree(path, ignore_errors=True)

    return RegisterEventHandler(OnShutdown(on_shutdown=remove))


def _node(context, *args, **kwargs):
    share = get_package_share_directory(PACKAGE)
    files = parameter_files(share, LaunchConfiguration('params_file').perform(context),
                            LaunchConfiguration('preset').perform(context))
    sim_time = LaunchConfiguration('use_sim_time').perform(context).lower() == 'true'
    scan = LaunchConfiguration('scan').perform(context)
    given = LaunchConfiguration('namespace').perform(context)
    nodes = [Node(package=PACKAGE, executable='tracker_node', name=NODE_NAME,
                  namespace=given or None, output='screen',
                  parameters=files + [{'use_sim_time': sim_time}],
                  remappings=[('scan', scan)])]
    if LaunchConfiguration('rviz').perform(context).lower() == 'true':
        out_dir = tempfile.mkdtemp(prefix='extended_tracker_rviz_')
        # a namespace pushed around this launch (PushRosNamespace) holds the node too
        pushed = context.launch_configurations.get('ros_namespace') or ''
        config = rviz_config(share, scan, out_dir, node_namespace(pushed, given))
        frame = LaunchConfiguration('rviz_frame').perform(context)
        nodes.append(Node(package='rviz2', executable='rviz2', name='rviz2',
                          namespace=given or None, arguments=['-d', config, '-f', frame],
                          parameters=[{'use_sim_time': sim_time}]))
        nodes.append(_remove_on_shutdown(out_dir))
    return nodes


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('scan', default_value='scan',
                              description='LaserScan topic to track'),
        DeclareLaunchArgument('preset', default_value='',
                              description='preset applied over the parameters, e.g. leg_height'),
        DeclareLaunchArgument('params_file', default_value='',
                              description='parameter file (default: the installed '
                                          'config/tracker.yaml)'),
        DeclareLaunchArgument('use_sim_time', default_value='false',
                              description='use /clock (a bag played with --clock)'),
        DeclareLaunchArgument('namespace', default_value='',
                              description='namespace of the node (one tracker per scanner: '
                                          'front, rear)'),
        DeclareLaunchArgument('rviz', default_value='false',
                              description='also start RViz2 with the scan and the tracks'),
        DeclareLaunchArgument('rviz_frame', default_value='odom',
                              description="RViz's fixed frame: the tracks' frame "
                                          '(tf.fixed_frame); the scan\'s frame_id for a '
                                          'scanner with no TF'),
        OpaqueFunction(function=_node),
    ])
