"""Reading and writing the configuration as YAML (an edge module: it adds PyYAML)."""

from __future__ import annotations

import yaml

from .config import from_dict, to_dict, TrackerConfig
from .errors import ConfigError


def load_yaml(path) -> TrackerConfig:
    """
    Load a config YAML: either plain sections or ROS ``/**: ros__parameters:`` form.

    Raises
    ------
    ConfigError
        When the file is unreadable, not a mapping, or holds a bad value.

    """
    try:
        with open(path, encoding='utf-8') as fh:
            data = yaml.safe_load(fh) or {}
    except (OSError, yaml.YAMLError) as err:
        msg = f'cannot read config {path}: {err}'
        raise ConfigError(msg) from err
    if not isinstance(data, dict):
        raise ConfigError(f'config {path} must be a mapping, got {type(data).__name__}')
    for node_key in list(data):
        sub = data[node_key]
        if isinstance(sub, dict) and 'ros__parameters' in sub:
            data = sub['ros__parameters']
            break
    return from_dict(data)


def dump_ros_yaml(cfg: TrackerConfig, node_name: str = '/**') -> str:
    """Return ``cfg`` as a ROS 2 parameters file (``/**: ros__parameters:`` form)."""
    return yaml.safe_dump({node_name: {'ros__parameters': to_dict(cfg)}}, sort_keys=False)
