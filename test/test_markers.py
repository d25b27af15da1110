"""Marker outlines: the ellipse, and the rectangle cars and bicycles are drawn as."""

import math

import numpy as np
import pytest

from extended_tracker.config import TrackerConfig
from extended_tracker.messages import (
    ELLIPSE_SEGMENTS, LINE_STRIP, markers_data, outline_xy, SHAPE_ELLIPSE, SHAPE_RECTANGLE,
    shapes, tracks_data,
)
from extended_tracker.pipeline import StepResult
from extended_tracker.state import Estimates


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
