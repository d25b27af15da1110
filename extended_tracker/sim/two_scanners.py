"""
Two scanners on opposite corners of a standing robot, out of step, and people walking
round it through both fields of view: the scene of several scanners feeding one tracker.
"""

from __future__ import annotations

import heapq
import math

from ..frames.pose import Placement, Pose2
from .laser import Drive, LaserSpec, Scene, SimObject, simulated_scans

#: the corners' mounts on the robot's base (x, y, yaw): front left, rear right
MOUNTS = {'front_laser': Pose2(0.35, 0.25, math.pi / 4),
          'rear_laser': Pose2(-0.35, -0.25, -3 * math.pi / 4)}


def two_scanner_scenes(rates=(10.0, 10.0)) -> list[Scene]:
    """One scene per scanner: the same people, room and robot (standing at the origin of
    ``base_link``, which is the fixed frame here), each scanner 270 deg / 0.5 deg / 12 m
    at its rate (10 Hz both by default), the rear one 0.05 s after the front one."""
    walls = (((-6.0, -5.0), (6.0, -5.0)), ((6.0, -5.0), (6.0, 5.0)),
             ((6.0, 5.0), (-6.0, 5.0)), ((-6.0, 5.0), (-6.0, -5.0)))
    people = (
        # circles the robot at 2.2 m, crossing both seams of the fields of view
        SimObject((2.2, 0.0), (0.0, 1.1), turn_rate=0.5, kind='circling'),
        SimObject((-4.5, 3.0), (1.0, -0.45), t_start=3.0, kind='crossing'),
        SimObject((3.5, -3.5), (-0.4, 0.9), t_start=2.0, kind='diagonal'),
    )
    scenes = []
    for k, (frame, mount) in enumerate(MOUNTS.items()):
        laser = LaserSpec(angle_min=-0.75 * math.pi, angle_max=0.75 * math.pi, n_beams=541,
                          range_max=12.0, frame_id=frame, phase=0.05 * k, rate_hz=rates[k])
        scenes.append(Scene(objects=people, walls=walls, laser=laser,
                            drive=Drive(((0.0, 0.0, 0.0, 0.0),), mount=mount,
                                        fixed_frame='base_link')))
    return scenes


def two_scanner_scans(duration: float, seed: int, scenes=None):
    """
    ``(scan, truth, place)`` of both scanners merged in stamp order: each scan with the
    truth at its time and its scanner's placement in ``base_link``.
    """
    scenes = scenes or two_scanner_scenes()

    def stream(k, scene):
        for j, (scan, truth) in enumerate(simulated_scans(scene, duration, seed + k)):
            t = j / scene.laser.rate_hz + scene.laser.phase
            stamp = scan.header.stamp.sec * 1_000_000_000 + scan.header.stamp.nanosec
            yield stamp, k, scan, truth, Placement(scene.drive.fixed_frame, scene.pose(t))

    for _, _, scan, truth, place in heapq.merge(*(stream(k, s) for k, s in
                                                   enumerate(scenes))):
        yield scan, truth, place


__all__ = ['two_scanner_scenes', 'two_scanner_scans', 'MOUNTS']
