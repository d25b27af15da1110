"""The environment every test runs in: loopback DDS and the installed ROS layout."""

import os
from pathlib import Path
import sys

import pytest

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
    assert (share / 'launch' / 'tracker.launch.py').is_file()
    assert (prefix / 'bin' / 'extended-tracker').exists()


def test_colcon_defaults_lists_both_packages():
    text = (ROOT / 'colcon_defaults.yaml').read_text()
    assert 'interfaces/extended_tracker_msgs' in text
    assert '- .' in text


def _bootstrap(tmp_path, candidates, **env):
    """Run the set-up script against a venv path that does not exist yet."""
    import subprocess

    full = dict(os.environ, EXTENDED_TRACKER_VENV=str(tmp_path / 'venv'),
                BOOTSTRAP_PYTHONS=' '.join(candidates), **env)
    full.pop('PYTHON', None)
    return subprocess.run(['bash', str(ROOT / 'tools' / 'bootstrap.sh')], env=full,
                          capture_output=True, text=True, timeout=60)


def test_bootstrap_refuses_when_no_interpreter_can_build_the_messages(tmp_path):
    # a stand-in interpreter that fails the script's 3.11 + headers + venv check
    fake = tmp_path / 'python3.12'
    fake.write_text('#!/bin/sh\nexit 1\n')
    fake.chmod(0o755)
    out = _bootstrap(tmp_path, [str(tmp_path / 'missing'), str(fake)])
    assert out.returncode == 1
    assert 'no Python 3.11 with its headers' in out.stdout
    assert not (tmp_path / 'venv').exists()             # nothing half made


@pytest.mark.slow
def test_bootstrap_takes_the_first_usable_interpreter_in_its_order(tmp_path):
    # the interpreter running the tests passed the check when its venv was made; a
    # candidate before it that fails the check is skipped. Stopped right after the venv is
    # created (no wheels installed): a pip that cannot start ends the script.
    fake = tmp_path / 'python3.12'
    fake.write_text('#!/bin/sh\nexit 1\n')
    fake.chmod(0o755)
    real = os.path.realpath(sys.executable)
    out = _bootstrap(tmp_path, [str(fake), real], PIP_NO_INDEX='1',
                     PIP_CONSTRAINT=str(tmp_path / 'absent.txt'))
    assert f'creating venv at {tmp_path / "venv"} with {real}' in out.stdout
    assert os.path.realpath(tmp_path / 'venv' / 'bin' / 'python') == real
