"""Between ROS messages and the package's plain data (the only place that knows both)."""

from __future__ import annotations

from functools import lru_cache
import importlib

import numpy as np


@lru_cache(maxsize=None)
def _element_class(msg_cls, field: str):
    """Message class of the elements of a sequence or array field (None for primitives)."""
    slot = msg_cls.SLOT_TYPES[msg_cls.__slots__.index('_' + field)]
    value_type = getattr(slot, 'value_type', None)
    if value_type is None or not hasattr(value_type, 'namespaces'):
        return None
    module = importlib.import_module('.'.join(value_type.namespaces))
    return getattr(module, value_type.name)


@lru_cache(maxsize=None)
def _shared_defaults(msg_cls, present: frozenset) -> dict:
    """
    One default instance for each message-typed field of ``msg_cls`` absent from the data.

    These are never filled (fill only writes the fields present), so every new message can
    share them; a Marker then skips building its texture image and mesh file (and a DELETE
    marker its lifetime).
    """
    shared = {}
    for name in msg_cls.get_fields_and_field_types():
        if name in present:
            continue
        default = getattr(msg_cls(), name)
        if hasattr(default, 'get_fields_and_field_types'):
            shared[name] = default
    return shared


def fill(msg, data: dict):
    """Set the fields of an rclpy message from nested plain data; returns ``msg``."""
    for name, value in data.items():
        if isinstance(value, dict):
            fill(getattr(msg, name), value)
        elif isinstance(value, list) and value and isinstance(value[0], dict):
            cls = _element_class(type(msg), name)
            if all(isinstance(x, float) for x in value[0].values()):
                # flat elements (points, colours): one constructor call each
                setattr(msg, name, [cls(**v) for v in value])
            else:
                setattr(msg, name, [fill(cls(**_shared_defaults(cls, frozenset(v))), v)
                                    for v in value])
        elif isinstance(value, np.ndarray):
            current = getattr(msg, name)
            if isinstance(current, np.ndarray):
                setattr(msg, name, value.astype(current.dtype))
            else:
                setattr(msg, name, value.tolist())
        else:
            setattr(msg, name, value)
    return msg


def to_plain(msg):
    """Nested plain data of an rclpy or rosbags message (for comparisons and tests)."""
    if hasattr(msg, 'get_fields_and_field_types'):
        return {k: to_plain(getattr(msg, k)) for k in msg.get_fields_and_field_types()}
    if hasattr(msg, '__dataclass_fields__'):
        # rosbags dataclasses list message constants (upper case) among their fields
        return {k: to_plain(getattr(msg, k)) for k in msg.__dataclass_fields__
                if not k.startswith('__') and not k.isupper()}
    if isinstance(msg, (list, tuple)):
        return [to_plain(v) for v in msg]
    if isinstance(msg, np.ndarray):
        return [to_plain(v) for v in msg.tolist()]
    if hasattr(msg, 'tolist'):
        return msg.tolist()
    return msg
