"""
``ros2 launch extended_tracker tracker.launch.py [scan:=/front/scan] [preset:=leg_height]
[params_file:=/path/to/tracker.yaml] [use_sim_time:=true]``

Starts ``tracker_node`` with the installed ``config/tracker.yaml`` (or ``params_file``),
then the preset's changes (``config/<preset>.yaml``) when one is named, and the input topic
remapped to ``scan``. ``use_sim_time`` for a bag played with ``ros2 bag play --clock``.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

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


def _node(context, *args, **kwargs):
    share = get_package_share_directory(PACKAGE)
    files = parameter_files(share, LaunchConfiguration('params_file').perform(context),
                            LaunchConfiguration('preset').perform(context))
    sim_time = LaunchConfiguration('use_sim_time').perform(context).lower() == 'true'
    return [Node(package=PACKAGE, executable='tracker_node', name='extended_tracker',
                 output='screen', parameters=files + [{'use_sim_time': sim_time}],
                 remappings=[('scan', LaunchConfiguration('scan').perform(context))])]


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
        OpaqueFunction(function=_node),
    ])
