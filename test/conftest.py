"""Test-wide settings: DDS stays on this machine, Hypothesis is deterministic."""

import os

# Before anything can initialise rclpy: discovery on loopback only (the default multicasts
# to the network); ROS_LOCALHOST_ONLY is deprecated in Jazzy and must not override it.
os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.pop('ROS_LOCALHOST_ONLY', None)
# A domain of this test process's own: two test runs on one machine (or a robot's graph on
# localhost) must not see each other's topics. Domains 1..100 stay within the port range.
os.environ['ROS_DOMAIN_ID'] = str(1 + os.getpid() % 100)
os.environ.setdefault('MPLBACKEND', 'Agg')

from hypothesis import HealthCheck, settings  # noqa: E402

settings.register_profile(
    'deterministic',
    derandomize=True,
    deadline=None,
    max_examples=60,
    suppress_health_check=[HealthCheck.too_slow],
    database=None,
)
settings.load_profile('deterministic')
