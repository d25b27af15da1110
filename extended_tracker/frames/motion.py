"""
How the scanner moved in the fixed frame between two scans: a jump of the frame itself
(a localisation reset) is no motion to carry tracks across.
"""

from __future__ import annotations

import math

from .pose import Pose2

#: a jump of the fixed frame is at least this far (m, rad), whatever the scan period
MIN_JUMP = 0.2


def frame_jump(last: Pose2 | None, pose: Pose2, dt: float, cfg):
    """
    ``(event, error)`` of a scanner pose that moved from the last scan's faster than
    ``tf.jump_speed`` or turned faster than ``tf.jump_turn_rate`` (and at least
    :data:`MIN_JUMP`): the fixed frame jumped (a localisation reset, a relocalised map),
    and tracks carried across would smear. ``(None, None)`` otherwise.
    """
    if last is None:
        return None, None
    metres, radians = last.distance_to(pose)
    if (metres > max(cfg.tf.jump_speed * dt, MIN_JUMP)
            or radians > max(cfg.tf.jump_turn_rate * dt, MIN_JUMP)):
        return 'frame_jump', (f'the scanner moved {metres:.2f} m and turned '
                              f'{math.degrees(radians):.0f} deg in the fixed frame in '
                              f'{dt:.3f} s (a localisation reset?): tracks restarted')
    return None, None


__all__ = ['frame_jump', 'MIN_JUMP']
