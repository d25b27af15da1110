"""package.xml declares what the code imports, and layers import one way."""

import ast
from pathlib import Path
import sys
import xml.etree.ElementTree as ET

ROOT = Path(__file__).resolve().parents[1]
PKG = ROOT / 'extended_tracker'

# Python module -> rosdep key in package.xml
ROSDEP_OF = {
    'numpy': 'python3-numpy',
    'scipy': 'python3-scipy',
    'yaml': 'python3-yaml',
    'matplotlib': 'python3-matplotlib',
    'pytest': 'python3-pytest',
    'hypothesis': 'python3-hypothesis',
}
# Imported but without a rosdep key (checked against rosdistro's rosdep/python.yaml); the
# README says how to install them. package.xml mentions each in a comment.
NO_ROSDEP_KEY = {'rosbags'}
ROS_MODULES = {
    'rclpy', 'sensor_msgs', 'visualization_msgs', 'geometry_msgs', 'std_msgs',
    'builtin_interfaces', 'rcl_interfaces', 'extended_tracker_msgs', 'ament_index_python',
    'std_srvs', 'diagnostic_msgs',
}
# The core: numpy/scipy only. Bag I/O may add rosbags; only extended_tracker.ros may add ROS.
CORE_ALLOWED = {'numpy', 'scipy'}
# Edge layers outside ros/: bag I/O, reports and plots, evaluation, the command line.
# They may add rosbags, yaml and matplotlib, never rclpy or message packages.
EDGE_PACKAGES = {'bag', 'report', 'evaluation'}
EDGE_MODULES = {'configio.py', 'cli.py', 'sim/bag.py'}


def _imports(path):
    tree = ast.parse(path.read_text())
    mods = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            mods.update(a.name.split('.')[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            mods.add(node.module.split('.')[0])
    return mods


def _declared(tags):
    root = ET.parse(ROOT / 'package.xml').getroot()
    return {e.text.strip() for t in tags for e in root.findall(t)}


def _third_party(mods):
    std = set(sys.stdlib_module_names)
    return {m for m in mods if m not in std and m != 'extended_tracker'}


def test_runtime_imports_are_declared():
    declared = _declared(['depend', 'exec_depend'])
    used = set()
    for f in PKG.rglob('*.py'):
        used |= _third_party(_imports(f))
    text = (ROOT / 'package.xml').read_text()
    for mod in sorted(used):
        if mod in NO_ROSDEP_KEY:
            assert f'pip install {mod}' in text, f'package.xml should say how to get {mod}'
            continue
        key = ROSDEP_OF.get(mod, mod)
        if mod == 'ament_index_python':
            key = 'ament_index_python'
        assert key in declared, f'{f}: imports {mod}, package.xml lacks {key}'


def test_test_imports_are_declared():
    declared = _declared(['depend', 'exec_depend', 'test_depend'])
    files = list((ROOT / 'test').rglob('*.py'))
    helpers = {f.stem for f in files}              # the tests' own modules (test/mixtures.py)
    for f in files:
        for mod in _third_party(_imports(f)) - NO_ROSDEP_KEY - helpers:
            key = ROSDEP_OF.get(mod, mod)
            assert key in declared, f'{f.name}: imports {mod}, package.xml lacks {key}'


def test_core_layers_import_one_way():
    for f in PKG.rglob('*.py'):
        rel = f.relative_to(PKG)
        mods = _third_party(_imports(f))
        if rel.parts[0] == 'ros':
            continue
        if rel.parts[0] in EDGE_PACKAGES or rel.as_posix() in EDGE_MODULES:
            assert not (mods & ROS_MODULES), f'{rel} imports ROS: {sorted(mods & ROS_MODULES)}'
            continue
        assert mods <= CORE_ALLOWED, f'core module {rel} imports {sorted(mods - CORE_ALLOWED)}'


def test_one_version_everywhere(capsys):
    """package.xml (both packages), setup.py, the module and `extended-tracker --version`
    give the same version."""
    import re

    import pytest

    from extended_tracker import __version__
    from extended_tracker.cli import main

    xml = [ET.parse(p).getroot().findtext('version') for p in (
        ROOT / 'package.xml', ROOT / 'interfaces' / 'extended_tracker_msgs' / 'package.xml')]
    (setup,) = re.findall(r"version='([^']+)'", (ROOT / 'setup.py').read_text())
    assert xml == [setup, setup] and __version__ == setup
    with pytest.raises(SystemExit) as done:
        main(['--version'])
    assert done.value.code == 0
    assert capsys.readouterr().out.strip() == f'extended-tracker {setup}'
