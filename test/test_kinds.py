"""
What each track is (``tracks.kinds``), and the edge cases of people who stand still, run
through the whole pipeline with the defaults on ray-cast scenes.
"""

import math

import numpy as np
import pytest

from extended_tracker.config import from_dict
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.sim.laser import (
    LaserSpec, mixed_traffic_scene, Scene, SimObject, simulate, tutorial_scene, walls_scene,
)
from extended_tracker.sim.leg_scenes import at_leg_height
from extended_tracker.tracks import kinds as K
from extended_tracker.tracks.estimates import Estimates


@pytest.mark.parametrize('moved, size, top, paired, want', [
    (True, 0.25, 1.2, False, (K.PERSON, 0.8)),
    (True, 0.25, 1.2, True, (K.PERSON, 0.9)),
    (True, 1.5, 2.0, False, (K.VEHICLE, 0.6)),
    (True, 0.3, 5.0, False, (K.VEHICLE, 0.6)),
    (True, 1.5, 5.0, False, (K.VEHICLE, 0.8)),
    (False, 0.2, 0.0, True, (K.PERSON, 0.6)),
    (False, 0.03, 0.0, False, (K.STATIC, 0.7)),
    (False, 0.9, 0.0, False, (K.STATIC, 0.7)),
    (False, 0.25, 0.0, False, (K.UNKNOWN, 0.5)),
])
def test_the_class_guess_follows_its_rules(moved, size, top, paired, want):
    assert K.guess(moved, size, top, paired) == want


def estimates(labels, m, semi):
    n = len(labels)
    X = np.array([np.diag([s * s, (0.5 * s) ** 2]) for s in semi]).reshape(n, 2, 2)
    return Estimates(np.asarray(labels, np.int64), np.ones(n), np.asarray(m, float).reshape(n, 4),
                     np.broadcast_to(np.eye(4), (n, 4, 4)).copy(), X, np.full(n, 10.0),
                     np.zeros(n, np.int64), np.ones(n))


def test_the_history_is_smoothed_as_a_reference_loop_smooths_it():
    rng = np.random.default_rng(1)
    semis, speeds = rng.uniform(0.1, 0.4, 30), rng.uniform(0.0, 2.0, 30)
    kinds, dt = K.TrackKinds(), 0.1
    size = speed = top = None
    for k, (s, v) in enumerate(zip(semis, speeds)):
        moved = k >= 10
        kinds = kinds.updated(estimates([4], [[0, 0, v, 0]], [s]), dt, np.array([4] if moved
                                                                              else []), [])
        a, b = 1 - math.exp(-dt / K.SIZE_TIME), 1 - math.exp(-dt / K.SPEED_TIME)
        size = s if size is None else size + a * (s - size)
        speed = v if speed is None else speed + b * (v - speed)
        top = max(top or 0.0, speed if moved else 0.0)
    assert kinds.size[0] == pytest.approx(size) and kinds.speed[0] == pytest.approx(speed)
    assert kinds.top_speed[0] == pytest.approx(top) and kinds.moved[0]
    # a label reported again after a scan without it starts over
    kinds = kinds.updated(estimates([], np.zeros((0, 4)), []), dt, [], [])
    kinds = kinds.updated(estimates([4], [[0, 0, 0, 0]], [0.2]), dt, [], [])
    assert not kinds.moved[0] and kinds.size[0] == pytest.approx(0.2)


def run(scene, seconds, cfg=None, seed=1):
    """Every step result of a scene with the defaults (clutter on random beams)."""
    cfg = cfg or from_dict({'model': {'clutter_density': 'beam'}})
    state, out = PipelineState.initial(cfg), []
    for scan, truth in simulate(scene, seconds, seed):
        state, res = step(state, scan, cfg)
        out.append((res, truth))
    return out


def near(res, xy, radius=0.5):
    """Rows of ``res``'s estimates within ``radius`` of ``xy``."""
    d = np.linalg.norm(res.estimates.m[:, :2] - np.asarray(xy), axis=1)
    return (d <= radius).nonzero()[0]


@pytest.mark.parametrize('legs', [False, True])
def test_a_person_standing_from_start_up_is_reported_and_never_moved(legs):
    """The tutorial's stander, at body and at leg height: reported from the first
    scans to the last, one id, never moved, class unknown (a laser cannot tell them from a
    bin until they move); the walkers are moving people."""
    scene = at_leg_height(tutorial_scene()) if legs else tutorial_scene()
    out = run(scene, 12.0)
    ids = set()
    for res, _ in out[5:]:
        (j,) = near(res, (2.5, 0.0))
        ids.add(int(res.estimates.label[j]))
        assert (res.motion[j], res.kind[j]) == (K.NEVER_MOVED, K.UNKNOWN)
    assert len(ids) == 1
    res, truth = out[-1]
    for t in truth[1:]:
        (j,) = near(res, t.centre)
        assert (res.motion[j], res.kind[j]) == (K.MOVING, K.PERSON)


def test_an_object_that_stands_still_is_learned_after_object_time():
    cfg = from_dict({'model': {'clutter_density': 'beam'}, 'background': {'object_time': 3.0}})
    scene = Scene(objects=(SimObject((2.5, 0.0), kind='standing'),), laser=LaserSpec())
    out = run(scene, 5.0, cfg)
    shown = [len(near(res, (2.5, 0.0))) for res, _ in out]
    assert all(shown[5:25]) and not any(shown[35:])


def test_a_walker_who_stops_is_paused_and_stays_a_person():
    out = run(walls_scene(), 12.0, seed=6)
    states = [(int(r.motion[0]), int(r.kind[0])) for r, _ in out if len(r.estimates) == 1]
    assert (K.MOVING, K.PERSON) in states[:30]
    assert states[-1] == (K.PAUSED, K.PERSON)


def test_the_car_of_mixed_traffic_is_a_vehicle():
    out = run(mixed_traffic_scene(), 6.0, seed=3)
    res, truth = out[-1]
    car = next(t for t in truth if t.kind == 'car')
    (j,) = near(res, car.centre, 1.0)
    assert res.kind[j] == K.VEHICLE


LEG_LASER = LaserSpec(n_beams=513, range_max=10.0)


def one_id(out, xy_of, first=10, radius=0.5):
    """The ids reported within ``radius`` of the truth returned by ``xy_of(truth)`` from
    scan ``first`` on, and the scans with none."""
    ids, missed = set(), 0
    for res, truth in out[first:]:
        rows = near(res, xy_of(truth), radius)
        missed += not len(rows)
        ids.update(res.estimates.label[rows].tolist())
    return ids, missed


def test_edge_cases_say_what_the_tracker_does():
    """A person at the edge of the view, one leaning on a wall, a child, a dog, and a
    scanner so low that feet and legs merge: each is one id."""
    wall = (((3.0, -3.0), (3.0, 3.0)),)
    cases = {
        # standing from start-up across the edge of a 90 deg view
        'edge': Scene(objects=(SimObject((2.0, 0.05), kind='standing'),),
                      laser=LaserSpec(angle_min=-math.pi / 2, angle_max=0.0, n_beams=181)),
        # standing from start-up, their back 0.05 m off a wall
        'leaning': Scene(objects=(SimObject((2.75, 1.0), kind='standing', a=0.2, b=0.25),),
                         walls=wall, laser=LEG_LASER),
        # a child-sized single cluster walking past
        'child': Scene(objects=(SimObject((2.0, -3.0), (0.0, 1.0), a=0.1, b=0.08),),
                       laser=LEG_LASER),
        # a dog trotting round in a curve
        'dog': Scene(objects=(SimObject((4.0, -2.0), (0.0, 1.5), a=0.3, b=0.1,
                                        turn_rate=-0.2),), laser=LEG_LASER),
        # at ankle height: one cluster for both feet and legs, swinging along the path
        'feet': Scene(objects=(SimObject((2.0, -3.0), (0.0, 1.0), a=0.3, b=0.12),),
                      laser=LEG_LASER),
    }
    kinds = {}
    for name, scene in cases.items():
        out = run(scene, 5.0)
        ids, missed = one_id(out, lambda truth: truth[0].centre)
        assert len(ids) == 1 and missed == 0, name
        res = out[-1][0]
        kinds[name] = K.CLASS_NAMES[res.kind[0]]
    # what the class guess says of them: it has no class for children or dogs
    assert kinds == {'edge': 'unknown', 'leaning': 'unknown', 'child': 'person',
                     'dog': 'person', 'feet': 'person'}


def test_a_walker_passing_a_post_is_no_leg_pair_with_it():
    """At leg height a walker passes 0.35 m from a post that stood there since start-up:
    the post keeps its id and place, the walker theirs (the post is settled, the walker
    not, so they are no pair)."""
    post = SimObject((2.0, 0.0), a=0.05, b=0.05, kind='post')
    walker = SimObject((2.45, -3.0), (0.0, 1.0), shape='legs', t_start=2.0)
    out = run(Scene(objects=(post, walker), laser=LEG_LASER), 8.0)
    posts, _ = one_id(out, lambda truth: truth[0].centre, radius=0.2)
    assert len(posts) == 1
    walkers, missed = one_id(out[25:], lambda truth: truth[1].centre, first=0, radius=0.2)
    assert len(walkers) == 1 and missed <= 2
    assert not posts & walkers
    last = out[-1][0]
    (j,) = near(last, (2.0, 0.0), 0.1)
    assert last.motion[j] == K.NEVER_MOVED
