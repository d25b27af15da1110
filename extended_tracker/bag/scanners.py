"""
Which scanners a bag holds and where they are: its LaserScan topics grouped by frame
(topics that share a frame are one scanner published twice), their mounts from a file
where the bag has no transforms for them, and the frame the replay tracks in.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..config import TrackerConfig
from ..errors import BagError
from ..frames.buffer import TransformBuffer
from ..frames.pose import Pose2
from .transforms import linked, links, root, tf_connections


@dataclass(frozen=True)
class Mounts:
    """Scanner mounts on a robot's ``base_frame``: ``{scanner frame: Pose2}``."""

    base_frame: str = ''
    poses: dict = field(default_factory=dict)

    def tree(self) -> dict[str, str]:
        return {frame: self.base_frame for frame in self.poses}

    def add_to(self, buffer: TransformBuffer) -> None:
        """Put the mounts into ``buffer`` as static transforms."""
        for frame, p in self.poses.items():
            buffer.set_transform(self.base_frame, frame, 0, (p.x, p.y, 0.0), p.quaternion,
                                 static=True)


def load_mounts(path) -> Mounts:
    """
    A mounts file: ``base_frame: NAME`` and ``mounts: {FRAME: [x, y, yaw], ...}`` (m,
    rad). BagError with the reason when it cannot be read or is malformed.
    """
    import yaml

    try:
        data = yaml.safe_load(Path(path).read_text())
        base = data['base_frame']
        poses = {str(f): Pose2(*(float(v) for v in xyz)) for f, xyz in data['mounts'].items()}
    except (OSError, yaml.YAMLError, KeyError, TypeError, ValueError, AttributeError) as err:
        raise BagError(f'cannot read the mounts {path}: {err!r} (base_frame: NAME, and '
                       f'mounts: {{FRAME: [x, y, yaw]}})') from err
    if not isinstance(base, str) or not base or not poses:
        raise BagError(f'{path}: base_frame must name a frame and mounts give at least one')
    return Mounts(base, poses)


def frame_of_topic(reader, conn) -> str:
    """The frame of a topic's first scan (ROS 1's leading ``/`` dropped)."""
    for c, _, raw in reader.messages(connections=[conn]):
        return reader.deserialize(raw, c.msgtype).header.frame_id.lstrip('/') or ''
    return ''


def one_per_scanner(reader, conns) -> tuple[list, dict, list[str]]:
    """
    ``(connections, {topic: frame}, notes)``: of topics that share a frame (one scanner
    published twice), only the one with the most scans, and a note saying so.
    """
    frames = {c.topic: frame_of_topic(reader, c) for c in conns}
    by_frame: dict[str, list] = {}
    for c in conns:
        by_frame.setdefault(frames[c.topic], []).append(c)
    kept, notes = [], []
    for frame, group in sorted(by_frame.items()):
        topics = sorted({c.topic for c in group},
                        key=lambda t: (-sum(c.msgcount for c in group if c.topic == t), t))
        kept += [c for c in group if c.topic == topics[0]]
        if len(topics) > 1:
            notes.append(f'{", ".join(topics)} share the frame {frame!r}: one scanner, '
                         f'{topics[0]} taken (the most scans)')
    return kept, {c.topic: frames[c.topic] for c in kept}, notes


def choose_frame(reader, frames: list[str], cfg: TrackerConfig, mounts: Mounts,
                 asked: str | None = None) -> tuple[str, str]:
    """
    ``(frame, why)``: the frame a replay tracks in. ``asked`` (``--fixed-frame``) when
    given ('' for the scan frame); else ``tf.fixed_frame`` where the bag's transforms
    (and the mounts) link every scanner to it; else, for several scanners, the mounts'
    base frame, or the one frame the transforms link them through; else the scan frame
    (''). BagError for several scanners that nothing links.
    """
    if asked is not None:
        return asked, 'as asked'
    tf_conns = tf_connections(reader)
    tree = {**(links(reader, tf_conns) if tf_conns else {}), **mounts.tree()}
    want = cfg.tf.fixed_frame
    if want and all(linked(tree, f, want) for f in frames):
        by = "the bag's transforms" if tf_conns else 'the mounts'
        return want, f'{by} link {", ".join(map(repr, frames))} to it'
    if len(frames) == 1:
        return '', ('tf.fixed_frame is empty' if not want else 'the bag has no transforms'
                    if not tf_conns else f'the bag\'s transforms do not link '
                    f'{frames[0]!r} to {want!r}')
    if mounts.base_frame and all(linked(tree, f, mounts.base_frame) for f in frames):
        return mounts.base_frame, 'the mounts place the scanners on it'
    roots = {root(tree, f) for f in frames}
    if len(roots) == 1:
        (common,) = roots
        return common, 'the bag\'s transforms link the scanners through it'
    raise BagError(f'nothing links the scanners\' frames {", ".join(map(repr, frames))}: '
                   f'give their mounts (--mounts FILE) or one --scan-topic')


__all__ = ['Mounts', 'load_mounts', 'one_per_scanner', 'choose_frame']
