"""Test-wide settings: DDS stays on this machine, Hypothesis is deterministic; the
``saved_figures`` fixture."""

import atexit
import os
import shutil
import tempfile

# Before anything can initialise rclpy: discovery on loopback only (the default multicasts
# to the network); ROS_LOCALHOST_ONLY is deprecated in Jazzy and must not override it.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)
# A domain of this test process's own: two test runs on one machine (or a robot's graph on
# localhost) must not see each other's topics. Domains 1..100 stay within the port range.
os.environ['ROS_DOMAIN_ID'] = str(1 + os.getpid() % 100)
os.environ.setdefault('MPLBACKEND', 'Agg')
# rcl writes a log file per context (some 70 a run) under ~/.ros/log: this run's go to a
# folder removed at its end, unless ROS_LOG_DIR names where to keep them
if 'ROS_LOG_DIR' not in os.environ:
    _logs = tempfile.mkdtemp(prefix='extended_tracker_test_logs_')
    os.environ['ROS_LOG_DIR'] = _logs
    atexit.register(shutil.rmtree, _logs, ignore_errors=True)

from hypothesis import HealthCheck, settings  # noqa: E402
import pytest  # noqa: E402

settings.register_profile(
    'deterministic',
    derandomize=True,
    deadline=None,
    max_examples=60,
    suppress_health_check=[HealthCheck.too_slow],
    database=None,
)
settings.load_profile('deterministic')


@pytest.fixture
def saved_figures(monkeypatch):
    """The matplotlib figures saved while the test runs, in order (each still written):
    what a picture draws is read off the figure, not off the PNG's pixels."""
    import matplotlib.figure

    saved = []
    save = matplotlib.figure.Figure.savefig

    def keep(fig, *args, **kwargs):
        saved.append(fig)
        return save(fig, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, 'savefig', keep)
    return saved
