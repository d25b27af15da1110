"""The environment every test runs in: loopback DDS and the installed ROS layout."""

import os
from pathlib import Path
import sys

ROOT = Path(__file__).resolve().parents[1]


def test_dds_discovery_is_loopback_only():
    assert os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE') == 'LOCALHOST'
    assert 'ROS_LOCALHOST_ONLY' not in os.environ
    assert 1 <= int(os.environ['ROS_DOMAIN_ID']) <= 100      # a domain of the test run's own


def test_ros2_run_layout_and_ament_index():
    """`ros2 run extended_tracker tracker_node` runs <prefix>/lib/extended_tracker/tracker_node."""
    from ament_index_python.packages import get_package_prefix, get_package_share_directory

    prefix = Path(sys.prefix)
    os.environ.setdefault('AMENT_PREFIX_PATH', str(prefix))
    assert Path(get_package_prefix('extended_tracker')) == prefix
    exe = prefix / 'lib' / 'extended_tracker' / 'tracker_node'
    assert exe.exists() and os.access(exe, os.X_OK)
    share = Path(get_package_share_directory('extended_tracker'))
    assert (share / 'package.xml').is_file()
    assert (share / 'config' / 'tracker.yaml').is_file()
    assert (prefix / 'bin' / 'extended-tracker').exists()


def test_colcon_defaults_lists_both_packages():
    text = (ROOT / 'colcon_defaults.yaml').read_text()
    assert 'interfaces/extended_tracker_msgs' in text
    assert '- .' in text
