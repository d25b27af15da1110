"""
The node's parameters: one ROS parameter per configuration field, its descriptor (type,
range, description) from the field's metadata, and the one-line errors for a value the
descriptor refuses.
"""

from __future__ import annotations

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType

from ..config import iter_leaves, leaf_kind, to_flat, TrackerConfig
from ..configio import double_hint, DOUBLE_LIST_HINT
from ..errors import ConfigError

_PTYPE = {'bool': ParameterType.PARAMETER_BOOL, 'int': ParameterType.PARAMETER_INTEGER,
          'float': ParameterType.PARAMETER_DOUBLE, 'str': ParameterType.PARAMETER_STRING,
          'list': ParameterType.PARAMETER_DOUBLE_ARRAY}


def parameter_descriptors(cfg: TrackerConfig | None = None) -> dict:
    """``{dotted_name: (default, ParameterDescriptor)}`` for every configuration field."""
    cfg = cfg or TrackerConfig()
    out = {}
    for name, f, value in iter_leaves(cfg):
        meta = f.metadata
        kind = leaf_kind(f)
        desc = ParameterDescriptor(name=name, type=_PTYPE[kind])
        unit = f' [{meta["unit"]}]' if meta['unit'] else ''
        text = meta['description'] + unit
        if meta['choices']:
            text += f'; one of {", ".join(meta["choices"])}'
        desc.description = text
        if kind == 'float' and meta['min'] is not None and meta['max'] is not None:
            desc.floating_point_range = [FloatingPointRange(
                from_value=float(meta['min']), to_value=float(meta['max']), step=0.0)]
        if kind == 'int' and meta['min'] is not None and meta['max'] is not None:
            desc.integer_range = [IntegerRange(
                from_value=int(meta['min']), to_value=int(meta['max']), step=1)]
        out[name] = (value, desc)
    return out


def type_error(name: str, expected: int, err: Exception) -> str:
    """The start-up error for a parameter given with a type the node does not take."""
    want = {ParameterType.PARAMETER_DOUBLE: 'a double',
            ParameterType.PARAMETER_INTEGER: 'an integer',
            ParameterType.PARAMETER_BOOL: 'a bool', ParameterType.PARAMETER_STRING: 'a string',
            ParameterType.PARAMETER_DOUBLE_ARRAY: 'a list of doubles'}[expected]
    hint = {ParameterType.PARAMETER_DOUBLE: f' ({double_hint()})',
            ParameterType.PARAMETER_DOUBLE_ARRAY: f' ({DOUBLE_LIST_HINT})'}
    said = str(err).removesuffix(f': {name}')        # rclpy's text, without the name again
    return f'{name} must be {want}{hint.get(expected, "")}; {said}'


def range_error(name: str, desc: ParameterDescriptor, value) -> str:
    """The start-up error for a parameter given outside its descriptor's range."""
    ranges = desc.floating_point_range or desc.integer_range
    span = f' [{ranges[0].from_value:g}, {ranges[0].to_value:g}]' if ranges else ''
    return f'{name} = {value!r} is out of its range{span}: {desc.description}'




def declare_scanner_parameters(node) -> None:
    """
    Declare the node's own ``scan_topics`` (the LaserScan topics of the scanners to
    track, ``[scan]`` by default, so that ``-r scan:=...`` keeps working) and ``mounts``
    (:func:`parse_mounts`), both read at start-up.
    """
    import rclpy
    from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException

    desc = ParameterDescriptor(
        name='scan_topics', type=ParameterType.PARAMETER_STRING_ARRAY, read_only=True,
        description='LaserScan topics of the scanners to track, all in one tracker in '
                    'tf.fixed_frame (placed there by TF)')
    try:
        topics = node.declare_parameter('scan_topics', ['scan'], desc).value
    except (InvalidParameterTypeException, InvalidParameterValueException) as err:
        raise ConfigError(f'scan_topics must be a list of topic names; {err}') from err
    if not topics or not all(isinstance(t, str) and t for t in topics):
        raise ConfigError(f'scan_topics must name at least one topic, got {topics!r}')
    mounts = ParameterDescriptor(
        name='mounts', type=ParameterType.PARAMETER_STRING_ARRAY,
        description='scanner mounts nothing publishes on /tf_static: '
                    '"PARENT CHILD X Y YAW" (m, rad) each; read at start-up')
    node.declare_parameter('mounts', rclpy.Parameter.Type.STRING_ARRAY, mounts)
    if node.get_parameter_or('mounts').value is None:   # GetParameters answers for it
        node.set_parameters([rclpy.Parameter('mounts', rclpy.Parameter.Type.STRING_ARRAY,
                                             [])])


def parse_mounts(entries) -> list:
    """
    ``[(parent, child, Pose2), ...]`` of the ``mounts`` parameter: entries
    ``"PARENT CHILD X Y YAW"`` (m, rad), a scanner's mount on the robot where nothing
    publishes it on ``/tf_static``. ConfigError with the entry otherwise.
    """
    from ..frames.pose import Pose2

    out = []
    for entry in entries:
        parts = str(entry).split()
        try:
            if len(parts) != 5 or parts[0] == parts[1]:
                raise ValueError('five fields, two distinct frames')
            out.append((parts[0], parts[1], Pose2(*(float(v) for v in parts[2:]))))
        except ValueError as err:
            raise ConfigError(f'mounts entry {entry!r} must be "PARENT CHILD X Y YAW" (m, '
                              f'rad): {err}') from err
    return out


def unknown_overrides(node) -> tuple[list, list]:
    """
    ``(names, said)``: the names given to ``node`` (a parameter file, ``-p``,
    overrides) that it does not have, and each as said in the log, with the nearest
    known name. rclpy ignores them, so a misspelt parameter would otherwise leave its
    default in force without a word. (The offline tools refuse an unknown key outright;
    a parameter file's ``/**`` section may hold other nodes' parameters, so the node
    runs on.)
    """
    import difflib

    # rclpy keeps what it was given in Node._parameter_overrides (Jazzy has no public
    # accessor); a release without it makes this check say nothing, not fail
    unknown = sorted(name for name in getattr(node, '_parameter_overrides', {})
                     if not node.has_parameter(name))
    known = list(to_flat(TrackerConfig())) + ['scan_topics', 'mounts']
    said = []
    for name in unknown:
        near = difflib.get_close_matches(name, known, n=1)
        said.append(f'{name} (did you mean {near[0]}?)' if near else name)
    return unknown, said


__all__ = ['declare_scanner_parameters', 'parameter_descriptors', 'type_error', 'range_error', 'unknown_overrides',
           'parse_mounts']
