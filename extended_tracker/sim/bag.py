"""Write simulated scans to a ROS 2 bag (MCAP) with the ground truth beside it (JSON)."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np

from . import laser
from .. import stopping
from ..bag.bagio import build_message, message_typestore, scan_data, SCAN_TYPE, staged_bag
from ..errors import BagError

SCENE_OF = {
    'tutorial': laser.tutorial_scene,
    'occlusion': laser.occlusion_scene,
    'mixed_traffic': laser.mixed_traffic_scene,
    'walls': laser.walls_scene,
    'demo': laser.demo_scene,
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
    with staged_bag(out) as tmp:
        with Writer(tmp, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            conn = writer.add_connection(topic, SCAN_TYPE, typestore=store)
            for scan, objs in laser.simulated_scans(sim_scene, duration, seed):
                stopping.check()
                stamp = scan.header.stamp.sec * 1_000_000_000 + scan.header.stamp.nanosec
                msg = build_message(store, SCAN_TYPE, scan_data(scan))
                digest.update(scan_ranges_bytes(msg))
                writer.write(conn, stamp, store.serialize_cdr(msg, SCAN_TYPE))
                truth.append({'stamp_ns': stamp, 'objects': [
                    {'id': o.id, 'kind': o.kind, 'centre': o.centre.tolist(),
                     'velocity': o.velocity.tolist(), 'extent': o.extent.tolist(),
                     'visible_beams': o.visible_beams} for o in objs]})
        L = sim_scene.laser
        info = {'scene': scene, 'seed': seed, 'duration_s': duration, 'scans': len(truth),
                'topic': topic, 'bag': str(out), 'truth': str(out / 'truth.json'),
                # the scans this truth belongs to: evaluate checks a replay holds these
                'scan_digest': digest.hexdigest(),
                # the region the scanner covers: evaluate scores over it
                'view': [L.angle_min, L.angle_max, L.range_max]}
        (tmp / 'truth.json').write_text(json.dumps({'info': info, 'scans': truth}))
    return info
