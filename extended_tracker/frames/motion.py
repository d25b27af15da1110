"""
How time went and how the scanner moved between two scans: a step back in time, a gap,
or a jump of the fixed frame itself (a localisation reset) is no motion to carry tracks
across.
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


def scan_period(last_ns: int | None, now_ns: int, cfg):
    """
    ``(dt, event, error)`` of a scan at ``now_ns`` after one at ``last_ns``.

    The first scan takes ``timing.default_dt``. A stamp earlier than the previous one (a
    bag looping, a clock jump) is event ``time_backwards``, a gap longer than
    ``timing.max_gap`` event ``time_gap``: the tracks restart and the scan takes
    ``timing.default_dt``.
    """
    default = cfg.timing.default_dt
    if last_ns is None:
        return default, None, None
    if now_ns < last_ns:
        return default, 'time_backwards', (
            f'stamp {(last_ns - now_ns) * 1e-9:.3f} s before the previous scan\'s (a bag '
            f'that looped, or a clock jump?): tracks restarted')
    dt = (now_ns - last_ns) * 1e-9
    if dt > cfg.timing.max_gap:
        return default, 'time_gap', (
            f'{dt:.3f} s since the previous scan, over timing.max_gap '
            f'({cfg.timing.max_gap:g} s): tracks restarted')
    return dt, None, None


__all__ = ['frame_jump', 'MIN_JUMP', 'scan_period']
