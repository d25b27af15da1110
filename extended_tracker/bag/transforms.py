"""
The transforms of a bag: ``/tf`` and ``/tf_static`` (tf2_msgs/TFMessage, ROS 1 or ROS 2)
fed into a :class:`frames.buffer.TransformBuffer`, and written back out as read.
"""

from __future__ import annotations

from ..frames.buffer import TransformBuffer

TF_TYPE = 'tf2_msgs/msg/TFMessage'
TF_TOPICS = {'/tf': False, '/tf_static': True, 'tf': False, 'tf_static': True}


def tf_connections(reader) -> list:
    """The bag's connections of ``/tf`` and ``/tf_static``."""
    return [c for c in reader.connections if c.msgtype == TF_TYPE and c.topic in TF_TOPICS]


def is_static(conn) -> bool:
    return TF_TOPICS[conn.topic]


def stamp_of(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def feed(buffer: TransformBuffer, msg, static: bool) -> int:
    """Add every transform of a TFMessage; returns how many were refused (a zero
    quaternion, a frame linked to itself)."""
    refused = 0
    for ts in msg.transforms:
        t, q = ts.transform.translation, ts.transform.rotation
        try:
            buffer.set_transform(ts.header.frame_id, ts.child_frame_id, stamp_of(ts.header),
                                 (t.x, t.y, t.z), (q.x, q.y, q.z, q.w), static)
        except ValueError:
            refused += 1
    return refused


def links(reader, conns) -> dict[str, str]:
    """``{child: parent}`` of every transform in ``conns`` (a pass over them)."""
    out = {}
    for conn, _, raw in reader.messages(connections=conns):
        for ts in reader.deserialize(raw, conn.msgtype).transforms:
            out[ts.child_frame_id.lstrip('/')] = ts.header.frame_id.lstrip('/')
    return out


def root(tree: dict[str, str], frame: str) -> str:
    """The root of ``frame`` in a tree of ``{child: parent}`` (itself when unknown)."""
    seen = set()
    while frame in tree and frame not in seen:
        seen.add(frame)
        frame = tree[frame]
    return frame


def linked(tree: dict[str, str], a: str, b: str) -> bool:
    """Whether frames ``a`` and ``b`` are in one tree of ``{child: parent}``."""
    return root(tree, a) == root(tree, b)


def tf_data(msg) -> dict:
    """Plain data of a TFMessage for :func:`bagio.build_message` (frames as ROS 2 names
    them, without a leading ``/``)."""
    out = []
    for ts in msg.transforms:
        t, q = ts.transform.translation, ts.transform.rotation
        out.append({
            'header': {'stamp': {'sec': ts.header.stamp.sec,
                                 'nanosec': ts.header.stamp.nanosec},
                       'frame_id': ts.header.frame_id.lstrip('/')},
            'child_frame_id': ts.child_frame_id.lstrip('/'),
            'transform': {'translation': {'x': t.x, 'y': t.y, 'z': t.z},
                          'rotation': {'x': q.x, 'y': q.y, 'z': q.z, 'w': q.w}}})
    return {'transforms': out}


__all__ = ['tf_connections', 'feed', 'links', 'linked', 'root', 'tf_data', 'TF_TYPE', 'is_static']
