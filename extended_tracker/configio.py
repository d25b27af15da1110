"""Reading and writing the configuration as YAML (an edge module: it adds PyYAML)."""

from __future__ import annotations

from collections.abc import Hashable
import re

import yaml

from .config import from_dict, from_flat, TrackerConfig
from .errors import ConfigError

NODE_NAME = 'extended_tracker'
# parameters every ROS 2 node has (rclpy declares them), not the tracker's: a node's
# parameter file may set them, and the offline tools pass over them
ROS_NODE_PARAMETERS = ('use_sim_time', 'start_type_description_service')
ROS_NODE_PREFIXES = ('qos_overrides.',)


class _Loader(yaml.SafeLoader):
    """
    PyYAML's safe loader reading numbers and repeated keys as ROS 2 reads a parameter
    file (rcl_yaml_param_parser), so that a file the node takes, the offline tools take
    the same way:

    - a plain scalar ``strtod`` reads whole is a number: ``1e-5`` and ``2E+0`` are
      doubles (YAML 1.1, PyYAML's, wants a decimal point and made them strings);
    - ``y``, ``Y``, ``n`` and ``N`` are booleans, as ``yes`` and ``no`` are;
    - a key written twice in one mapping merges: a repeated section or node entry adds
      its parameters, a parameter given twice takes the later value (PyYAML kept only
      the later mapping, dropping what the earlier one set).
    """

    bool_values = {**yaml.SafeLoader.bool_values, 'y': True, 'n': False}

    def construct_mapping(self, node, deep=False):
        self.flatten_mapping(node)
        out = {}
        for key_node, value_node in node.value:
            key = self.construct_object(key_node, deep=deep)
            if not isinstance(key, Hashable):
                raise yaml.constructor.ConstructorError(
                    'while constructing a mapping', node.start_mark, 'found unhashable key',
                    key_node.start_mark)
            value = self.construct_object(value_node, deep=deep)
            out[key] = _merged(out[key], value) if key in out else value
        return out


def _merged(old, new):
    """``new`` over ``old`` as a repeated key: two mappings merged key by key, else
    ``new``."""
    if not (isinstance(old, dict) and isinstance(new, dict)):
        return new
    out = dict(old)
    for k, v in new.items():
        out[k] = _merged(out[k], v) if k in out else v
    return out


_Loader.add_constructor('tag:yaml.org,2002:map', _Loader.construct_mapping)
_Loader.add_implicit_resolver('tag:yaml.org,2002:bool', re.compile(r'^[yYnN]$'), list('yYnN'))
# decimal numbers with an exponent as strtod reads them: YAML 1.1 wants a point and a
# signed exponent (1.5e+5), so 1e5, 1.5e5 and 5.e3 were strings
_Loader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'^[-+]?([0-9]+(\.[0-9]*)?|\.[0-9]+)[eE][-+]?[0-9]+$'), list('-+.0123456789'))


def load_yaml(path) -> TrackerConfig:
    """
    Load a config YAML: plain sections, or a ROS 2 parameter file.

    A parameter file is read as the tracker node would read it: the entries for its node
    (``/**``, ``/*``, ``extended_tracker``, ``/ns/extended_tracker``, nested under
    namespaces or not), in file order, later ones over earlier ones; nested or dotted
    parameter names; other nodes' entries and the parameters every ROS node has
    (``use_sim_time``, ``qos_overrides.*``) passed over.

    Raises
    ------
    ConfigError
        When the file is unreadable, not a mapping, holds a bad value, or is a parameter
        file with no entry for the tracker node.

    """
    try:
        with open(path, encoding='utf-8') as fh:
            data = yaml.load(fh, Loader=_Loader) or {}       # noqa: S506 (a safe loader)
    except (OSError, yaml.YAMLError) as err:
        # PyYAML's messages run over several lines (problem, context, position): one
        msg = f'cannot read config {path}: {" ".join(str(err).split())}'
        raise ConfigError(msg) from err
    if not isinstance(data, dict):
        raise ConfigError(f'config {path} must be a mapping, got {type(data).__name__}')
    entries = list(_ros_entries(data, ()))
    if not entries:
        return from_dict(data)
    for names, params in entries:
        # rcl refuses the whole file over any node's entry that is not a mapping, an
        # empty one included ("Cannot have a value before ros__parameters")
        if not isinstance(params, dict):
            raise ConfigError(f'{"/".join(names)} in {path}: ros__parameters must be a '
                              f'mapping, got {params!r} (ROS refuses the file; write {{}} '
                              'for no parameters)')
    mine = [(names, params) for names, params in entries if _for_this_node(names)]
    if not mine:
        found = ', '.join('/'.join(names) for names, _ in entries)
        raise ConfigError(f'{path} has no parameters for the {NODE_NAME} node (its '
                          f'entries: {found})')
    spaces = sorted({ns for ns in map(_namespace, (names for names, _ in mine)) if ns})
    if len(spaces) > 1:                   # a node runs in one: which, only the user knows
        raise ConfigError(f'{path} has {NODE_NAME} entries for several namespaces '
                          f'({", ".join(spaces)}); give a file with one')
    flat = {}
    for names, params in mine:
        flat.update(_flattened(params, ''))
    flat = {k: v for k, v in flat.items() if k not in ROS_NODE_PARAMETERS
            and not k.startswith(ROS_NODE_PREFIXES)}
    _as_ros_types(flat, path)
    return from_flat(flat)


def double_hint(value=2) -> str:
    """How to write ``value`` for a double parameter (ROS refuses ``2`` for one)."""
    return f'a whole number needs its decimal point: {value}.0, not {value}'


# the same for a list of doubles
DOUBLE_LIST_HINT = 'whole numbers need their decimal points: [1.0, 2.0], not [1, 2]'


def _as_ros_types(flat: dict, path) -> None:
    """
    Refuse what the node refuses in a parameter file and the plain sections take: a
    whole number written without its decimal point for a double parameter (ROS types
    parameters strictly; the node stops at start-up on it), so that a file a replay
    accepts also starts the node.
    """
    from .config import iter_leaves, leaf_kind

    def whole(v):
        return isinstance(v, int) and not isinstance(v, bool)

    for name, f, _ in iter_leaves(TrackerConfig()):
        value = flat.get(name)
        kind = leaf_kind(f)
        if kind == 'float' and whole(value):
            raise ConfigError(f'{name} in {path} must be a double ({double_hint(value)}), '
                              'as the node takes it')
        if kind == 'list' and isinstance(value, list) and any(map(whole, value)):
            raise ConfigError(f'{name} in {path} must be a list of doubles '
                              f'({DOUBLE_LIST_HINT}), as the node takes it')


def _ros_entries(data: dict, names: tuple):
    """``(key path, ros__parameters)`` of each node entry of a parameter file, in order."""
    for key, sub in data.items():
        if isinstance(sub, dict):
            if 'ros__parameters' in sub:
                yield names + (str(key),), sub['ros__parameters']
            else:
                yield from _ros_entries(sub, names + (str(key),))


def _for_this_node(names: tuple) -> bool:
    """Whether an entry's key path names the tracker node (or every node)."""
    last = names[-1].strip('/').split('/')[-1]
    return last in (NODE_NAME, '*', '**')


def _namespace(names: tuple) -> str:
    """The namespace an entry names its node in; '' when it applies in any (wildcards)."""
    parts = [p for n in names for p in str(n).split('/') if p]
    if not parts or parts[-1] != NODE_NAME or any('*' in p for p in parts):
        return ''
    return '/' + '/'.join(parts[:-1])


def _flattened(params: dict, prefix: str):
    """Nested parameter mappings as dotted names, as ROS gives them to the node."""
    for key, value in params.items():
        if isinstance(value, dict):
            yield from _flattened(value, f'{prefix}{key}.')
        else:
            yield f'{prefix}{key}', value


def _yaml_value(value) -> str:
    """One value as inline YAML (as both generated files write it)."""
    return yaml.safe_dump(value, default_flow_style=True).strip().removesuffix('...').strip()


def dump_ros_yaml(cfg: TrackerConfig, node_name: str = '/**') -> str:
    """
    ``cfg`` as a ROS 2 parameters file (``/**: ros__parameters:``), one comment per field
    with its description, unit and valid range.
    """
    from dataclasses import fields

    lines = [f'{node_name}:', '  ros__parameters:']
    for section in fields(cfg):                    # every field of the tree is a section
        sub = getattr(cfg, section.name)
        doc = (type(sub).__doc__ or '').strip().splitlines()[0]
        lines.append(f'    {section.name}:  # {doc}')
        for f in fields(sub):
            meta = f.metadata
            value = _yaml_value(getattr(sub, f.name))
            rng = ''
            if meta.get('choices'):
                rng = ' {' + ', '.join(meta['choices']) + '}'
            elif meta.get('min') is not None:
                lo = '(' if meta.get('lo_open') else '['
                rng = f' {lo}{meta["min"]:g}, {meta["max"]:g}]'
            unit = f' [{meta["unit"]}]' if meta.get('unit') else ''
            lines.append(f'      {f.name}: {value}  # {meta["description"]}{unit}{rng}')
    return '\n'.join(lines) + '\n'


YAML_HEADER = (
    '# extended_tracker: the documented default configuration, generated from\n'
    '# extended_tracker/config.py (test/test_node.py keeps them equal).\n'
    '# ros2 run extended_tracker tracker_node --ros-args --params-file config/tracker.yaml\n'
)


def default_yaml() -> str:
    """The text of ``config/tracker.yaml``: regenerate with ``make config``."""
    return YAML_HEADER + dump_ros_yaml(TrackerConfig())


def preset_yaml(name: str) -> str:
    """
    The text of ``config/<name>.yaml``: the preset's changes only, as a ROS 2 parameters
    file, each with its description and the default it replaces.
    """
    from dataclasses import fields

    from .config import preset, PRESETS

    cfg = preset(name)                                 # validates the preset
    base = TrackerConfig()
    lines = [
        f'# extended_tracker preset {name!r}: changes from config/tracker.yaml, generated',
        '# from PRESETS in extended_tracker/config.py (test/test_config.py keeps them equal).',
        f'# ros2 run extended_tracker tracker_node --ros-args --params-file config/{name}.yaml',
        f'# extended-tracker replay BAG -o OUT --preset {name}',
        '/**:', '  ros__parameters:',
    ]
    for section, changes in PRESETS[name].items():
        lines.append(f'    {section}:')
        meta = {f.name: f.metadata for f in fields(getattr(base, section))}
        for key in changes:
            value = getattr(getattr(cfg, section), key)
            old = getattr(getattr(base, section), key)
            unit = f' {meta[key]["unit"]}' if meta[key].get('unit') else ''
            lines.append(f'      {key}: {_yaml_value(value)}  # {meta[key]["description"]} '
                         f'(default {_yaml_value(old)}{unit})')
    return '\n'.join(lines) + '\n'


PARAMETERS_BEGIN = '<!-- parameters:begin -->'
PARAMETERS_END = '<!-- parameters:end -->'


def parameter_table() -> str:
    """
    The README's parameter table: every parameter of the node with its default, unit,
    valid range and description, from the same field metadata the node's parameter
    descriptors are made of (``make config`` writes it).
    """
    from .config import iter_leaves

    rows = ['| parameter | default | unit, range | description |', '|---|---|---|---|']
    for name, f, value in iter_leaves(TrackerConfig()):
        meta = f.metadata
        rows.append(f'| `{name}` | `{_yaml_value(value)}` | {_range_text(meta)} | '
                    f'{meta["description"]} |')
    return '\n'.join(rows)


def _range_text(meta: dict) -> str:
    """Unit and range of a field: ``m, (0, 2]``, ``one of cphd, phd`` or empty."""
    if meta.get('choices'):
        return 'one of ' + ', '.join(meta['choices'])
    lo, hi = meta.get('min'), meta.get('max')
    span = ''
    if lo is not None or hi is not None:
        left = '(' if meta.get('lo_open') else '['
        span = f'{left}{_number(lo, "-inf")}, {_number(hi, "inf")}]'
    return ', '.join(x for x in (meta.get('unit', ''), span) if x)


def _number(x, none: str) -> str:
    """A range limit, short: ``0.5``, ``1e+04``; ``none`` for no limit."""
    return none if x is None else f'{x:g}'



def write_readme_parameters(readme) -> None:
    """Replace the README's parameter table between its markers."""
    from pathlib import Path

    path = Path(readme)
    text = path.read_text()
    if PARAMETERS_BEGIN not in text or PARAMETERS_END not in text:
        raise ConfigError(f'{path} has no {PARAMETERS_BEGIN} ... {PARAMETERS_END} markers')
    head, rest = text.split(PARAMETERS_BEGIN, 1)
    _, tail = rest.split(PARAMETERS_END, 1)
    path.write_text(f'{head}{PARAMETERS_BEGIN}\n{parameter_table()}\n{PARAMETERS_END}{tail}')


if __name__ == '__main__':
    import sys

    if len(sys.argv) > 2 and sys.argv[1] == '--readme':
        write_readme_parameters(sys.argv[2])
    else:
        sys.stdout.write(preset_yaml(sys.argv[1]) if len(sys.argv) > 1 else default_yaml())
