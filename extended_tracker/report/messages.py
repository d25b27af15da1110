"""
What the tracker publishes, as plain nested data (no ROS imports).

:func:`tracks_data` describes an ``extended_tracker_msgs/ExtendedObjectArray`` and
:func:`markers_data` a ``visualization_msgs/MarkerArray`` for one :class:`StepResult`.
The node turns them into rclpy messages and the bag replay into rosbags messages, so both
publish the same thing by construction. Field names are the message fields.
"""

from __future__ import annotations

import math

import numpy as np

from ..tracks.kinds import CLASS_NAMES, MOTION_NAMES

SHAPE_ELLIPSE = 0
SHAPE_RECTANGLE = 1
# visualization_msgs/Marker constants
ARROW, LINE_STRIP, TEXT_VIEW_FACING = 0, 4, 9
ADD, DELETE = 0, 2
MARKER_NAMESPACES = ('outline', 'label', 'velocity')
ELLIPSE_SEGMENTS = 32


def _time(stamp_ns: int) -> dict:
    return {'sec': int(stamp_ns // 1_000_000_000), 'nanosec': int(stamp_ns % 1_000_000_000)}


def header_data(stamp_ns: int, frame_id: str) -> dict:
    return {'stamp': _time(stamp_ns), 'frame_id': frame_id}


def shapes(estimates, extraction_cfg) -> np.ndarray:
    """
    SHAPE_RECTANGLE for long objects, or elongated ones at least half that long (cars,
    bicycles); SHAPE_ELLIPSE otherwise (a pedestrian's one-sided contour is elongated
    but short).
    """
    if not len(estimates):
        return np.zeros(0, dtype=np.uint8)
    length, _ = estimates.rectangle()
    major, minor, _ = estimates.axes()
    elong = major / np.maximum(minor, 1e-6)
    long_ = length >= extraction_cfg.rectangle_length
    rect = long_ | ((elong >= extraction_cfg.rectangle_elongation)
                    & (length >= 0.5 * extraction_cfg.rectangle_length))
    return np.where(rect, SHAPE_RECTANGLE, SHAPE_ELLIPSE).astype(np.uint8)


def tracks_data(result, cfg) -> dict:
    """``ExtendedObjectArray`` of one step result."""
    e = result.estimates
    major, minor, yaw = e.axes()
    length, width = e.rectangle()
    shape = shapes(e, cfg.extraction)
    objects = []
    for j in range(len(e)):
        objects.append({
            'id': int(e.label[j]),
            'existence': float(e.existence[j]),
            'position': {'x': float(e.m[j, 0]), 'y': float(e.m[j, 1]), 'z': 0.0},
            'velocity': {'x': float(e.m[j, 2]), 'y': float(e.m[j, 3]), 'z': 0.0},
            'position_covariance': e.P[j, :2, :2].astype(float).ravel(),
            'velocity_covariance': e.P[j, 2:, 2:].astype(float).ravel(),
            'extent': e.X[j].astype(float).ravel(),
            'semi_major': float(major[j]),
            'semi_minor': float(minor[j]),
            'orientation': float(yaw[j]),
            'length': float(length[j]),
            'width': float(width[j]),
            'shape': int(shape[j]),
            'measurement_rate': float(e.rate[j]),
            'num_detections': int(e.num_detections[j]),
            'visibility': float(np.clip(e.visibility[j], 0.0, 1.0)),
            'age': float(result.age[j]),
            'time_since_detected': float(result.since_detected[j]),
            'motion': int(result.motion[j]),
            'object_class': int(result.kind[j]),
            'class_confidence': float(result.kind_confidence[j]),
        })
    return {
        'header': header_data(result.stamp_ns, result.frame_id),
        'objects': objects,
        'expected_count': float(result.expected_count),
        'cardinality': np.asarray(result.cardinality, dtype=float),
        'num_detections': int(result.diagnostics.get('detections', 0)),
        'processing_time': float(result.processing_time),
    }


def id_rgba(label: int) -> dict:
    """Stable colour of an id (golden-ratio hue walk)."""
    import colorsys

    h = (int(label) * 0.618033988749895) % 1.0
    r, g, b = colorsys.hsv_to_rgb(h, 0.75, 0.95)
    return {'r': float(r), 'g': float(g), 'b': float(b), 'a': 1.0}


def _pose(x=0.0, y=0.0, z=0.0) -> dict:
    """A position with the identity orientation (outlines and arrows are drawn in points)."""
    return {'position': {'x': float(x), 'y': float(y), 'z': float(z)},
            'orientation': {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0}}


def _marker(header, ns, mid, mtype, action, **kw) -> dict:
    m = {'header': header, 'ns': ns, 'id': int(mid), 'type': mtype, 'action': action,
         'pose': _pose(), 'scale': {'x': 0.0, 'y': 0.0, 'z': 0.0},
         'color': {'r': 0.0, 'g': 0.0, 'b': 0.0, 'a': 0.0}, 'points': [], 'text': '',
         'frame_locked': False}
    m.update(kw)
    return m


_THETA = np.linspace(0, 2 * math.pi, ELLIPSE_SEGMENTS + 1)
_CORNERS = np.array([(1, 1), (-1, 1), (-1, -1), (1, -1), (1, 1)], dtype=float)


def outline_xy(centre, major: float, minor: float, yaw: float, rectangle: bool) -> np.ndarray:
    """
    Closed outline (k, 2) of an extent with semi-axes ``major``, ``minor`` at ``yaw``: the
    ellipse ``(p-c)' X^-1 (p-c) = 1``, or the second-moment rectangle (sides
    ``sqrt(3)`` times the semi-axes, see ``Estimates.rectangle``).
    """
    u = np.array([math.cos(yaw), math.sin(yaw)])
    v = np.array([-u[1], u[0]])
    if rectangle:
        half = math.sqrt(3.0) / 2
        along, across = half * major * _CORNERS[:, 0], half * minor * _CORNERS[:, 1]
    else:
        along, across = major * np.cos(_THETA), minor * np.sin(_THETA)
    return np.asarray(centre) + np.outer(along, u) + np.outer(across, v)


def outline_points(centre, major: float, minor: float, yaw: float, rectangle: bool) -> list:
    """:func:`outline_xy` as ``geometry_msgs/Point`` dictionaries."""
    return [{'x': x, 'y': y, 'z': 0.0}
            for x, y in outline_xy(centre, major, minor, yaw, rectangle).tolist()]


def label_text(label: int, kind: int, confidence: float, motion: int) -> str:
    """An object's marker text: ``'7 person 0.8\nmoving'``."""
    return f'{label} {CLASS_NAMES[kind]} {confidence:.1f}\n{MOTION_NAMES[motion]}'


def markers_data(result, cfg, previous_ids=()) -> tuple[dict, set]:
    """
    ``MarkerArray`` of one step result, and the ids it shows.

    Per object: its outline (ellipse, or rectangle when ``shape`` says so), a text label
    with the id, its class guess and how sure, and its motion state (:func:`label_text`),
    a velocity arrow; colours fixed per id. Markers of ids shown before and
    gone now are deleted (``DELETE`` in each namespace), so RViz keeps no stale ghosts;
    each lives ``extraction.marker_lifetime`` so a stream that stops leaves none either.
    """
    e = result.estimates
    header = header_data(result.stamp_ns, result.frame_id)
    shape = shapes(e, cfg.extraction)
    major, minor, yaw = e.axes()
    life = _time(round(cfg.extraction.marker_lifetime * 1e9))
    markers = []
    ids = set()
    for j in range(len(e)):
        lab = int(e.label[j])
        ids.add(lab)
        col = id_rgba(lab)
        c = e.m[j, :2]
        markers.append(_marker(header, 'outline', lab, LINE_STRIP, ADD, lifetime=life,
                               scale={'x': 0.04, 'y': 0.0, 'z': 0.0}, color=col,
                               points=outline_points(c, major[j], minor[j], yaw[j],
                                                     shape[j] == SHAPE_RECTANGLE)))
        markers.append(_marker(header, 'label', lab, TEXT_VIEW_FACING, ADD, lifetime=life,
                               pose=_pose(c[0], c[1], 0.5),
                               text=label_text(lab, result.kind[j], result.kind_confidence[j],
                                               result.motion[j]),
                               scale={'x': 0.0, 'y': 0.0, 'z': 0.3}, color=col))
        tip = c + e.m[j, 2:4]
        markers.append(_marker(header, 'velocity', lab, ARROW, ADD, lifetime=life,
                               scale={'x': 0.05, 'y': 0.1, 'z': 0.1}, color=col,
                               points=[{'x': float(c[0]), 'y': float(c[1]), 'z': 0.0},
                                       {'x': float(tip[0]), 'y': float(tip[1]), 'z': 0.0}]))
    for lab in sorted(set(previous_ids) - ids):
        for ns in MARKER_NAMESPACES:
            markers.append(_marker(header, ns, lab, LINE_STRIP, DELETE))
    return {'markers': markers}, ids
