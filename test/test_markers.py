"""What is published: marker outlines (the ellipse, and the rectangle cars and bicycles are
drawn as), the other markers, and the fields of ExtendedObjectArray."""

import math

import numpy as np
import pytest

from extended_tracker.config import TrackerConfig
from extended_tracker.pipeline import StepResult
from extended_tracker.report.messages import (
    ELLIPSE_SEGMENTS, id_rgba, LINE_STRIP, markers_data, outline_xy, SHAPE_ELLIPSE,
    SHAPE_RECTANGLE, shapes, tracks_data,
)
from extended_tracker.tracks.estimates import Estimates


def estimates(rows):
    """Estimates of (label, x, y, semi_major, semi_minor, yaw) rows."""
    k = len(rows)
    m = np.zeros((k, 4))
    X = np.zeros((k, 2, 2))
    for j, (_, x, y, a, b, yaw) in enumerate(rows):
        m[j, :2] = x, y
        R = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        X[j] = R @ np.diag([a * a, b * b]) @ R.T
    return Estimates(np.array([r[0] for r in rows], np.int64), np.ones(k), m,
                     np.tile(np.eye(4) * 0.01, (k, 1, 1)), X, np.full(k, 10.0),
                     np.full(k, 10, np.int64), np.ones(k))


def second_moments(poly, n=400):
    """Area second moments of a convex polygon about its centroid, by a grid (an oracle
    independent of the outline's construction)."""
    lo, hi = poly.min(axis=0), poly.max(axis=0)
    g = np.stack(np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n)),
                 -1).reshape(-1, 2)
    inside = np.ones(len(g), bool)
    for p, q in zip(poly[:-1], poly[1:]):       # counter-clockwise: inside on the left
        inside &= (q[0] - p[0]) * (g[:, 1] - p[1]) - (q[1] - p[1]) * (g[:, 0] - p[0]) >= 0
    pts = g[inside]
    d = pts - pts.mean(axis=0)
    return d.T @ d / len(pts)


@pytest.mark.parametrize('yaw', [0.0, 0.4, -2.0])
def test_rectangle_outline_has_the_ellipse_second_moments(yaw):
    """A uniform ellipse with semi-axes a, b has second moments a^2/4, b^2/4; the drawn
    rectangle (sides sqrt(3) a, sqrt(3) b) has the same, about the same axes."""
    a, b, c = 2.2, 0.9, np.array([3.0, -1.0])
    rect = outline_xy(c, a, b, yaw, rectangle=True)
    assert rect.shape == (5, 2) and np.allclose(rect[0], rect[-1])
    sides = np.linalg.norm(np.diff(rect, axis=0), axis=1)
    np.testing.assert_allclose(sides, math.sqrt(3) * np.array([a, b, a, b]), rtol=1e-12)
    np.testing.assert_allclose(rect[:4].mean(axis=0), c, atol=1e-12)
    R = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
    want = R @ np.diag([a * a / 4, b * b / 4]) @ R.T
    np.testing.assert_allclose(second_moments(rect), want, atol=0.01)
    ellipse = outline_xy(c, a, b, yaw, rectangle=False)
    assert ellipse.shape == (ELLIPSE_SEGMENTS + 1, 2)
    local = (ellipse - c) @ R
    np.testing.assert_allclose((local[:, 0] / a) ** 2 + (local[:, 1] / b) ** 2, 1.0)


def test_cars_are_drawn_as_rectangles_and_people_as_ellipses():
    cfg = TrackerConfig()
    est = estimates([(1, 5.0, 0.0, 2.2, 0.9, 0.3),        # a car
                     (2, 3.0, 2.0, 0.25, 0.2, 0.0),       # a pedestrian
                     (3, 8.0, -2.0, 0.9, 0.2, 1.0)])      # a bicycle
    assert shapes(est, cfg.extraction).tolist() == [SHAPE_RECTANGLE, SHAPE_ELLIPSE,
                                                    SHAPE_RECTANGLE]
    res = StepResult(1_700_000_000_000_000_000, 'laser', est, np.ones(1), 3.0,
                     np.zeros((0, 2)), np.zeros((0, 2)), {})
    data, ids = markers_data(res, cfg)
    outlines = {mk['id']: mk for mk in data['markers'] if mk['ns'] == 'outline'}
    assert ids == {1, 2, 3} and all(mk['type'] == LINE_STRIP for mk in outlines.values())
    assert [len(outlines[i]['points']) for i in (1, 2, 3)] == [5, ELLIPSE_SEGMENTS + 1, 5]
    car = np.array([[p['x'], p['y']] for p in outlines[1]['points']])
    np.testing.assert_allclose(car, outline_xy((5.0, 0.0), 2.2, 0.9, 0.3, True))
    msg = tracks_data(res, cfg)
    assert [o['shape'] for o in msg['objects']] == [SHAPE_RECTANGLE, SHAPE_ELLIPSE,
                                                    SHAPE_RECTANGLE]
    assert msg['objects'][0]['length'] == pytest.approx(math.sqrt(3) * 2.2)
    assert msg['objects'][0]['width'] == pytest.approx(math.sqrt(3) * 0.9)


def test_the_messages_carry_every_field_of_the_estimates():
    """Field by field, ExtendedObjectArray and the markers against estimates built from
    known values: semi-axes and yaw (the extent is made from them), a covariance whose
    position block differs from its velocity block, a velocity whose components differ."""
    rows = [(7, 1.5, -2.0, 0.30, 0.20, 0.4), (12, -3.0, 4.0, 2.2, 0.9, -1.1),
            (30, 6.0, 0.5, 0.9, 0.2, 1.3)]
    est = estimates(rows)
    est.existence[:] = 0.9, 0.55, 1.0
    est.m[:, 2:] = [[0.5, -1.25], [8.0, 3.0], [-4.0, 0.75]]
    for j in range(3):
        A = np.arange(16.0).reshape(4, 4) * 0.01 * (j + 1)
        est.P[j] = A @ A.T + np.diag([0.04, 0.09, 0.5, 0.7])
    est.rate[:] = 12.0, 4.5, 30.0
    est.num_detections[:] = 9, 0, 25
    est.visibility[:] = 1.2, 0.4, -0.1            # rounding past [0, 1] is clipped
    cfg = TrackerConfig()
    res = StepResult(1_700_000_000_123_456_789, 'laser', est, np.array([0.1, 0.2, 0.7]), 2.6,
                     np.zeros((0, 2)), np.zeros((0, 2)), {'detections': 57, 'cells': 12},
                     processing_time=0.0042, motion=np.array([1, 0, 2], np.uint8),
                     kind=np.array([1, 3, 2], np.uint8),
                     kind_confidence=np.array([0.8, 0.7, 0.6]))
    msg = tracks_data(res, cfg)
    assert msg['header'] == {'stamp': {'sec': 1_700_000_000, 'nanosec': 123_456_789},
                             'frame_id': 'laser'}
    assert (msg['expected_count'], msg['num_detections'], msg['processing_time']) == (
        2.6, 57, 0.0042)
    np.testing.assert_array_equal(msg['cardinality'], [0.1, 0.2, 0.7])
    for j, (o, (lab, x, y, a, b, yaw)) in enumerate(zip(msg['objects'], rows)):
        assert o['id'] == lab and o['existence'] == est.existence[j]
        assert o['position'] == {'x': x, 'y': y, 'z': 0.0}
        assert o['velocity'] == {'x': est.m[j, 2], 'y': est.m[j, 3], 'z': 0.0}
        np.testing.assert_array_equal(o['position_covariance'], est.P[j, :2, :2].ravel())
        np.testing.assert_array_equal(o['extent'], est.X[j].ravel())
        assert o['semi_major'] == pytest.approx(a) and o['semi_minor'] == pytest.approx(b)
        assert o['orientation'] == pytest.approx(yaw)
        assert o['length'] == pytest.approx(math.sqrt(3) * a)
        assert o['width'] == pytest.approx(math.sqrt(3) * b)
        assert o['measurement_rate'] == est.rate[j]
        assert o['num_detections'] == est.num_detections[j]
        assert (o['motion'], o['object_class'], o['class_confidence']) == (
            res.motion[j], res.kind[j], res.kind_confidence[j])
    assert [o['visibility'] for o in msg['objects']] == [1.0, 0.4, 0.0]

    data, _ = markers_data(res, cfg)
    by = {(mk['ns'], mk['id']): mk for mk in data['markers']}
    for j, (lab, x, y, *_) in enumerate(rows):
        text, arrow = by['label', lab], by['velocity', lab]
        assert text['scale']['z'] > 0                                  # a visible height
        assert text['pose'] == {'position': {'x': x, 'y': y, 'z': 0.5},
                                'orientation': {'x': 0.0, 'y': 0.0, 'z': 0.0, 'w': 1.0}}
        # the arrow spans one second of motion from the centre
        assert arrow['points'] == [{'x': x, 'y': y, 'z': 0.0},
                                   {'x': x + est.m[j, 2], 'y': y + est.m[j, 3], 'z': 0.0}]
        assert arrow['scale']['x'] > 0 and arrow['scale']['y'] > 0
        assert by['outline', lab]['scale']['x'] > 0      # a line strip's width: visible
        assert by['outline', lab]['color'] == text['color'] == arrow['color']
        assert text['color']['a'] == 1.0
    # the text: id, class guess and how sure, motion state
    assert [by['label', r[0]]['text'] for r in rows] == [
        '7 person 0.8\nmoving', '12 static 0.7\nnever moved', '30 vehicle 0.6\npaused']
    # each id its own colour, over the first hundred ids
    colours = {tuple(id_rgba(lab).values()) for lab in range(1, 101)}
    assert len(colours) == 100


@pytest.mark.parametrize('a, b, want', [
    (1.2 / math.sqrt(3) * 1.001, 1.2 / math.sqrt(3), SHAPE_RECTANGLE),   # long enough
    (1.2 / math.sqrt(3) * 0.999, 1.2 / math.sqrt(3) * 0.9, SHAPE_ELLIPSE),
    (0.6 / math.sqrt(3) * 1.001, 0.6 / math.sqrt(3) / 2.5, SHAPE_RECTANGLE),  # half as long,
    (0.6 / math.sqrt(3) * 1.001, 0.6 / math.sqrt(3) / 2.4, SHAPE_ELLIPSE),    # elongated
    (0.6 / math.sqrt(3) * 0.999, 0.6 / math.sqrt(3) / 3.0, SHAPE_ELLIPSE),
])
def test_the_rectangle_thresholds(a, b, want):
    """Rectangles from ``rectangle_length`` (1.2 m) of second-moment length, or from half
    of it with semi-axes at least ``rectangle_elongation`` (2.5) to one."""
    assert shapes(estimates([(1, 0.0, 0.0, a, b, 0.3)]), TrackerConfig().extraction) == [want]


def test_a_zero_width_extent_is_drawn_without_dividing_by_zero():
    """A singular extent (a straight contour, semi-minor 0): a rectangle if long enough,
    an ellipse if not, the elongation taken without a division by zero."""
    cfg = TrackerConfig().extraction
    with np.errstate(all='raise'):
        assert shapes(estimates([(1, 0.0, 0.0, 1.0, 0.0, 0.3)]), cfg).tolist() == [
            SHAPE_RECTANGLE]
        assert shapes(estimates([(1, 0.0, 0.0, 0.0, 0.0, 0.0)]), cfg).tolist() == [
            SHAPE_ELLIPSE]


def test_markers_stay_where_the_scan_saw_the_objects():
    """Markers are not frame-locked: RViz places them with the transform at the scan's
    stamp, so on a moving robot an object's outline stays where it was seen instead of
    riding along with the sensor frame. The colours are bright on RViz's dark background
    (brightest channel 0.95) and saturated enough to tell ids apart (lowest channel at
    most a quarter of the brightest)."""
    est = estimates([(4, 2.0, 1.0, 0.3, 0.2, 0.0)])
    res = StepResult(1_700_000_000_000_000_000, 'laser', est, np.ones(2), 1.0,
                     np.zeros((0, 2)), np.zeros((0, 2)), {})
    data, _ = markers_data(res, TrackerConfig(), previous_ids={9})
    assert len(data['markers']) == 6 and not any(m['frame_locked'] for m in data['markers'])
    for lab in range(1, 101):
        rgb = [id_rgba(lab)[k] for k in 'rgb']
        assert max(rgb) == pytest.approx(0.95) and min(rgb) <= 0.25 * max(rgb) + 1e-12
