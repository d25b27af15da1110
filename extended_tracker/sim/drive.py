"""
A scene from a robot that drives: an L-shaped corridor, people walking both ways, one who
walks to the wall and stands there, one who overtakes the robot.
"""

from __future__ import annotations

import math

from ..frames.pose import Pose2
from .laser import Drive, LaserSpec, Scene, SimObject

#: the robot base's keyframes (t, x, y, yaw): 0.8 m/s along the corridor, a left turn into
#: the side corridor, on at 0.6 m/s
CORRIDOR_DRIVE = ((0.0, 0.0, 0.0, 0.0), (12.0, 9.6, 0.0, 0.0), (15.0, 11.4, 1.2, math.pi / 2),
                  (20.0, 11.4, 4.2, math.pi / 2))


def corridor_drive_scene() -> Scene:
    """
    The corridor runs along x (y from -2 to 2) to x = 13.5, the side corridor along y
    (x from 10 to 13.5). The scanner (270 deg, 0.5 deg, 13 m) sits 0.25 m ahead of the
    base. A cabinet stands against the wall; walls and cabinet come into view as the
    robot drives and turns.
    """
    walls = (
        ((-3.0, -2.0), (13.5, -2.0)), ((13.5, -2.0), (13.5, 12.0)),
        ((-3.0, 2.0), (10.0, 2.0)), ((10.0, 2.0), (10.0, 12.0)), ((-3.0, -2.0), (-3.0, 2.0)),
        ((5.0, -2.0), (5.0, -1.5)), ((5.0, -1.5), (6.2, -1.5)), ((6.2, -1.5), (6.2, -2.0)),
    )
    people = (
        SimObject((9.0, 0.7), (-1.1, 0.0), kind='oncoming'),
        SimObject((4.0, 1.5), (0.6, 0.0), stops=((4.0, math.inf),), kind='standing'),
        SimObject((-2.0, -0.9), (1.4, 0.0), t_start=1.0, t_end=11.0, kind='overtaking'),
        SimObject((11.0, 8.5), (0.0, -1.0), t_start=13.0, kind='side_corridor'),
        SimObject((12.5, 6.0), (0.0, 0.8), t_start=13.0, kind='ahead'),
    )
    laser = LaserSpec(angle_min=-0.75 * math.pi, angle_max=0.75 * math.pi, n_beams=541,
                      range_max=13.0)
    return Scene(objects=people, walls=walls, laser=laser,
                 drive=Drive(CORRIDOR_DRIVE, mount=Pose2(0.25, 0.0, 0.0)))


__all__ = ['corridor_drive_scene', 'CORRIDOR_DRIVE']
