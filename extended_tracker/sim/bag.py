"""Write simulated scans to a ROS 2 bag (MCAP) with the ground truth beside it (JSON)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from . import laser
from .. import stopping
from ..bag.bagio import build_message, message_typestore, scan_data, SCAN_TYPE, staged_bag
from ..bag.transforms import TF_TYPE
from ..errors import BagError
from .drive import corridor_drive_scene
from .leg_scenes import at_leg_height, counting_scene
from .two_scanners import two_scanner_scans, two_scanner_scenes

SCENE_OF = {
    'tutorial': laser.tutorial_scene,
    'occlusion': laser.occlusion_scene,
    'mixed_traffic': laser.mixed_traffic_scene,
    'walls': laser.walls_scene,
    'demo': laser.demo_scene,
    'corridor_drive': corridor_drive_scene,
    'two_scanners': two_scanner_scenes,
    'tutorial_legs': lambda: at_leg_height(laser.tutorial_scene()),
    'walls_legs': lambda: at_leg_height(laser.walls_scene()),
    'counting': lambda: counting_scene(8, seed=8),       # 8 people past a leg-height scanner
}

# the truth is held in memory until it is written at the end: an hour (36 000 scans at
# 10 Hz; mixed_traffic: a 231 MB bag, 0.55 GB resident, 67 s) is the most one bag holds;
# longer runs are several bags
MAX_DURATION = 3600.0


def scan_ranges_bytes(msg) -> bytes:
    """A LaserScan's ranges as the float32 bytes a bag holds (for ``scan_digest``)."""
    return np.asarray(msg.ranges, dtype=np.float32).tobytes()


def write_sim_bag(output, scene: str, seed: int, duration: float, topic: str = '/scan') -> dict:
    """
    Simulate ``scene`` and write ``output`` (a bag folder) and ``output/truth.json``.

    Raises
    ------
    BagError
        When ``output`` exists, ``scene`` is unknown, or ``duration`` or ``seed`` is out
        of range.

    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    out = Path(output)
    if out.exists():
        raise BagError(f'output {out} exists; refusing to overwrite it')
    if scene not in SCENE_OF:
        raise BagError(f'unknown scene {scene!r}; choose one of {sorted(SCENE_OF)}')
    if not 0 < duration <= MAX_DURATION:
        raise BagError(f'duration must be a positive number of seconds up to '
                       f'{MAX_DURATION:g}, got {duration}')
    if seed < 0:
        raise BagError(f'seed must be a non-negative integer, got {seed}')
    sim_scene = SCENE_OF[scene]()
    store = message_typestore()
    truth = []
    digest = hashlib.sha256()
    # written in a staging folder and moved into place with its truth: an interrupted
    # run leaves nothing at OUTPUT
    if isinstance(sim_scene, list):                 # one scene per scanner
        return _write_scanners(out, scene, sim_scene, seed, duration)
    with staged_bag(out) as tmp:
        with Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            conn = writer.add_connection(topic, SCAN_TYPE, typestore=store)
            tf = _TransformWriter(writer, store, sim_scene) if sim_scene.drive else None
            for k, (scan, objs) in enumerate(laser.simulated_scans(sim_scene, duration, seed)):
                stopping.check()
                stamp = scan.header.stamp.sec * 1_000_000_000 + scan.header.stamp.nanosec
                if tf is not None:
                    tf.write(stamp, k / sim_scene.laser.rate_hz)
                msg = build_message(store, SCAN_TYPE, scan_data(scan))
                digest.update(scan_ranges_bytes(msg))
                writer.write(conn, stamp, store.serialize_cdr(msg, SCAN_TYPE))
                truth.append({'stamp_ns': stamp, 'objects': [
                    {'id': o.id, 'kind': o.kind, 'centre': o.centre.tolist(),
                     'velocity': o.velocity.tolist(), 'extent': o.extent.tolist(),
                     'visible_beams': o.visible_beams} for o in objs]})
                if tf is not None:
                    pose = sim_scene.pose(k / sim_scene.laser.rate_hz)
                    truth[-1]['pose'] = [pose.x, pose.y, pose.yaw]
        L = sim_scene.laser
        info = {'scene': scene, 'seed': seed, 'duration_s': duration, 'scans': len(truth),
                'topic': topic, 'bag': str(out), 'truth': str(out / 'truth.json'),
                # the scans this truth belongs to: evaluate checks a replay holds these
                'scan_digest': digest.hexdigest(),
                # the region the scanner covers: evaluate scores over it
                'view': [L.angle_min, L.angle_max, L.range_max]}
        if sim_scene.drive is not None:     # truth in the fixed frame, the scanner posed
            info['fixed_frame'] = sim_scene.drive.fixed_frame
        (tmp / 'truth.json').write_text(json.dumps({'info': info, 'scans': truth}))
    return info


def _write_scanners(out: Path, name: str, scenes: list, seed: int, duration: float) -> dict:
    """
    A bag of several scanners, each on ``/<frame>/scan``, their mounts on the base frame
    (the fixed frame of their drive) in ``/tf_static``, and ``truth.json`` of every scan
    (no region: the scanners cover the whole scene together).
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = message_typestore()
    truth = []
    with staged_bag(out) as tmp:
        with Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            conns = {s.laser.frame_id: writer.add_connection(
                f'/{s.laser.frame_id}/scan', SCAN_TYPE, typestore=store) for s in scenes}
            static = writer.add_connection('/tf_static', TF_TYPE, typestore=store)
            for scan, objs, place in two_scanner_scans(duration, seed, scenes):
                stopping.check()
                stamp = scan.header.stamp.sec * 1_000_000_000 + scan.header.stamp.nanosec
                if not truth:
                    for s in scenes:
                        _put_transform(writer, store, static, stamp, s.drive.fixed_frame,
                                       s.laser.frame_id, s.drive.mount)
                msg = build_message(store, SCAN_TYPE, scan_data(scan))
                writer.write(conns[scan.header.frame_id], stamp,
                             store.serialize_cdr(msg, SCAN_TYPE))
                truth.append({'stamp_ns': stamp, 'objects': [
                    {'id': o.id, 'kind': o.kind, 'centre': o.centre.tolist(),
                     'velocity': o.velocity.tolist(), 'extent': o.extent.tolist(),
                     'visible_beams': o.visible_beams} for o in objs]})
        info = {'scene': name, 'seed': seed, 'duration_s': duration, 'scans': len(truth),
                'topic': ', '.join(sorted(c.topic for c in conns.values())), 'bag': str(out),
                'truth': str(out / 'truth.json'),
                'fixed_frame': scenes[0].drive.fixed_frame}
        (tmp / 'truth.json').write_text(json.dumps({'info': info, 'scans': truth}))
    return info


def _put_transform(writer, store, conn, ns: int, parent: str, child: str, pose) -> None:
    """One planar transform ``parent -> child`` at ``ns`` on ``conn``."""
    sec, nsec = divmod(ns, 1_000_000_000)
    qx, qy, qz, qw = pose.quaternion
    data = {'transforms': [{
        'header': {'stamp': {'sec': sec, 'nanosec': nsec}, 'frame_id': parent},
        'child_frame_id': child,
        'transform': {'translation': {'x': pose.x, 'y': pose.y, 'z': 0.0},
                      'rotation': {'x': qx, 'y': qy, 'z': qz, 'w': qw}}}]}
    msg = build_message(store, TF_TYPE, data)
    writer.write(conn, ns, store.serialize_cdr(msg, TF_TYPE))


class _TransformWriter:
    """The ``/tf`` (fixed -> base at every half scan period, the base's pose at that time)
    and ``/tf_static`` (base -> scanner, once) of a scene with a drive."""

    def __init__(self, writer, store, scene: laser.Scene):
        self.writer, self.store, self.drive = writer, store, scene.drive
        self.laser = scene.laser
        self.tf = writer.add_connection('/tf', TF_TYPE, typestore=store)
        self.static = writer.add_connection('/tf_static', TF_TYPE, typestore=store)
        self.first = True

    def write(self, stamp_ns: int, t: float) -> None:
        """The transforms of a scan at ``t`` (s) stamped ``stamp_ns``: the base's pose at
        it and half a period after (so that the scan's own stamp is always covered)."""
        d = self.drive
        if self.first:
            self.first = False
            self._put(self.static, stamp_ns, d.base_frame, self.laser.frame_id, d.mount)
        half = 0.5 / self.laser.rate_hz
        for dt in (0.0, half):
            ns = stamp_ns + int(round(dt * 1e9))
            self._put(self.tf, ns, d.fixed_frame, d.base_frame, d.base_pose(t + dt))

    def _put(self, conn, ns: int, parent: str, child: str, pose) -> None:
        _put_transform(self.writer, self.store, conn, ns, parent, child, pose)
