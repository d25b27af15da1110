"""Static background: walls and furniture vanish, a person who stops stays tracked."""

import numpy as np

from extended_tracker.config import from_dict
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.sensing.background import update_background
from extended_tracker.sensing.scan import scan_to_points
from extended_tracker.sim.laser import LaserSpec, Scene, simulate, SimObject, walls_scene


def run(scene, duration, cfg, seed=0):
    state = PipelineState.initial(cfg)
    out = []
    for scan, truth in simulate(scene, duration, seed=seed):
        state, res = step(state, scan, cfg)
        out.append((truth, res))
    return out


def test_walls_and_furniture_yield_no_tracks_and_a_stopped_person_stays_tracked():
    cfg = from_dict({})
    hist = run(walls_scene(), 20.0, cfg)
    # After the learning period (confirm_time 1 s, then the static tracks die out; all gone
    # by 5 s): nothing but the person. The person walks in at t = 1 s and stands still from
    # 4 s to 14 s.
    labels_on_person = []
    for k, (truth, res) in enumerate(hist):
        if k < 50:
            continue
        est = res.estimates
        (person,) = truth
        d = np.linalg.norm(est.m[:, :2] - person.centre, axis=1) if len(est) else np.zeros(0)
        on_person = d < 0.6
        assert np.sum(~on_person) == 0, (k, est.m[~on_person, :2])   # no static structure
        assert np.sum(on_person) == 1, k                               # the person, always
        labels_on_person.append(int(est.label[on_person][0]))
    assert len(set(labels_on_person)) == 1
    # background removal did its work: most returns of each scan were dropped
    dropped = np.mean([res.diagnostics['background_dropped'] for _, res in hist[50:]])
    assert dropped > 300


def test_without_background_the_walls_are_tracked():
    """The contrast: the static structure is what the background model removes."""
    cfg = from_dict({'background': {'enabled': False}})
    hist = run(walls_scene(), 3.0, cfg)
    assert np.mean([len(res.estimates) for _, res in hist[10:]]) >= 3


def test_moved_chair_is_forgotten():
    """A chair present at start-up, removed later: its beams re-learn the wall behind."""
    wall = (((6.0, -5.0), (6.0, 5.0)),)
    chair = SimObject((3.0, 0.0), a=0.3, b=0.3, kind='chair', t_end=5.0)
    cfg = from_dict({'background': {'confirm_time': 1.0}})
    hist = run(Scene((chair,), walls=wall, laser=LaserSpec()), 12.0, cfg)
    # chair gone at 5 s; the wall behind it is new "farther" background, learned after 1 s;
    # by 8 s nothing is tracked
    assert all(len(res.estimates) == 0 for _, res in hist[80:]), \
        [len(res.estimates) for _, res in hist[60:]]


def test_background_learning_unit():
    cfg = from_dict({}).background
    (scan, _), = simulate(Scene((), walls=(((5.0, -5.0), (5.0, 5.0)),),
                                laser=LaserSpec(noise_std=0.0, dropout=0.0)), 0.1, seed=0)
    sp = scan_to_points(scan)
    state, keep = update_background(None, sp, 0.1, cfg, np.zeros(len(sp.angles), bool))
    assert keep.all()                                 # nothing known yet
    for _ in range(12):                               # 1.2 s > confirm_time
        state, keep = update_background(state, sp, 0.1, cfg, np.zeros(len(sp.angles), bool))
    assert not keep.any()                             # the wall is background now
