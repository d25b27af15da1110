"""Static background: walls and furniture vanish, a person who stops stays tracked."""

from dataclasses import replace

import numpy as np
import pytest

from extended_tracker.config import from_dict
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.sensing.background import update_background
from extended_tracker.sensing.scan import scan_to_points
from extended_tracker.sim.laser import LaserSpec, Scene, SimObject, simulate, walls_scene
from extended_tracker.tracks.identity import record_reports
from extended_tracker.tracks.record import TrackRecord

from mixtures import estimates

# objects off: the per-beam rules alone, which learn whatever stands still (an object,
# at most background.object_size, is learned only after object_time: test_kinds.py)
NO_OBJECTS = {'background': {'object_size': 0.0}}


def run(scene, duration, cfg, seed=0):
    state = PipelineState.initial(cfg)
    out = []
    for scan, truth in simulate(scene, duration, seed=seed):
        state, res = step(state, scan, cfg)
        out.append((truth, res))
    return out


@pytest.mark.slow
def test_walls_and_furniture_yield_no_tracks_and_a_stopped_person_stays_tracked():
    cfg = from_dict({})
    hist = run(walls_scene(), 20.0, cfg)
    # From the end of the warm-up (1.5 s) on, nothing but the person: the walls behind the
    # person, hidden at start-up and revealed as the person walks in, continue the learned
    # walls and are learned at once (a wall piece was tracked in scans 19-35 before). The
    # person walks in at t = 1 s and stands still from 4 s to 14 s; from 5 s on, exactly
    # one report is on them.
    labels_on_person = []
    for k, (truth, res) in enumerate(hist):
        if k < 15:
            continue
        est = res.estimates
        (person,) = truth
        d = np.linalg.norm(est.m[:, :2] - person.centre, axis=1) if len(est) else np.zeros(0)
        on_person = d < 0.6
        assert np.sum(~on_person) == 0, (k, est.m[~on_person, :2])   # no static structure
        if k < 50:
            continue
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


def _empty_then(ranges_per_scan, cfg, protected):
    """Feed one beam's ranges (inf: no return) and return the last state and keep-mask."""
    (scan, _), = simulate(Scene((), laser=LaserSpec(n_beams=3)), 0.1, seed=0)
    state = keep = None
    for r in ranges_per_scan:
        scan.ranges = np.full(3, r, dtype=np.float32)
        sp = scan_to_points(scan)
        state, keep = update_background(state, sp, 0.1, cfg, protected)
    return state, keep


def test_beam_seen_empty_is_free_and_a_protecting_track_holds_it():
    cfg = from_dict({}).background                      # confirm_time 1 s
    yes, no = np.ones(3, bool), np.zeros(3, bool)
    # 1.2 s with nothing in range, then something stands there for 3 s
    ranges = [np.inf] * 12 + [4.0] * 30
    state, keep = _empty_then(ranges, cfg, protected=yes)
    assert state.free.all() and np.isnan(state.background).all()
    assert keep.all()                                   # a protecting track: never learned
    # no protecting track (a track that never moved is none): learned after confirm_time
    state, keep = _empty_then(ranges, cfg, protected=no)
    assert not keep.any() and np.allclose(state.background, 4.0)
    # never seen empty (0.5 s of nothing is not enough): tracks protect nothing there
    state, keep = _empty_then([np.inf] * 5 + [4.0] * 30, cfg, yes)
    assert not state.free.any() and not keep.any()
    # a beam with a known background never becomes free, however long it returns nothing
    state, _ = _empty_then([4.0] * 12 + [np.inf] * 30, cfg, no)
    assert not state.free.any() and np.allclose(state.background, 4.0)


def test_a_return_within_margin_of_the_background_is_background():
    """Learned at 4 m (margin 0.15 m): a return 0.12 m beyond is background and dropped,
    one 0.2 m beyond is not."""
    cfg = from_dict({}).background
    no = np.zeros(3, bool)
    _, keep = _empty_then([4.0] * 12 + [4.12], cfg, no)
    assert not keep.any()
    _, keep = _empty_then([4.0] * 12 + [4.2], cfg, no)
    assert keep.all()


def test_the_background_range_smooths_the_beams_returns_with_time_constant_learn_time():
    """A beam returning ranges that wander within the margin: its background range, once
    learned, is the exponential smoothing of every return from the first on, with gain
    dt / learn_time per scan (the candidate is refined so while it waits to be confirmed,
    and carried into the background). Oracle: the smoothing written as a loop."""
    cfg = from_dict({}).background                       # learn_time 2 s, confirm 1 s
    rng = np.random.default_rng(13)
    ranges = np.float32(4.0 + rng.uniform(-0.07, 0.07, 40))
    state, keep = _empty_then(ranges, cfg, np.zeros(3, bool))
    gain = 0.1 / cfg.learn_time
    want = float(ranges[0])
    for r in ranges[1:]:
        want += gain * (float(r) - want)
    assert not keep.any()
    np.testing.assert_allclose(state.background, want, rtol=1e-12)
    # after a pause longer than learn_time the gain is 1, not more: the background takes
    # the return, without overshooting it
    (scan, _), = simulate(Scene((), laser=LaserSpec(n_beams=3)), 0.1, seed=0)
    scan.ranges = np.full(3, 4.05, dtype=np.float32)
    state, _ = update_background(state, scan_to_points(scan), 2.5 * cfg.learn_time, cfg,
                                 np.zeros(3, bool))
    np.testing.assert_allclose(state.background, float(np.float32(4.05)), rtol=1e-12)


def test_neighbours_are_the_beams_within_margin_across_at_the_range():
    """Beams k apart at range r are neighbours while the arc between them, r k step, is
    at most margin: checked against the chord 2 r sin(k step / 2) a little inside and
    outside that range for every offset."""
    from extended_tracker.sensing.background import _OFFSETS, reach_of

    step, margin = np.radians(0.5), 0.15
    reach = reach_of(step, margin)
    for k, limit in zip(_OFFSETS.tolist(), reach.tolist()):
        if k == 0:
            assert limit == np.inf
            continue
        for r, near in ((0.95 * limit, True), (1.05 * limit, False)):
            assert (2 * r * np.sin(abs(k) * step / 2) <= margin) == near, (k, r)
            assert (r <= limit) == near


@pytest.mark.slow
def test_person_who_stops_in_open_space_keeps_one_id():
    """Nothing within range behind the person: the beams are free, the person is kept."""
    person = SimObject((12.0, 2.0), (-1.0, -0.2), t_start=2.0, stops=((6.0, 12.0),))
    hist = run(Scene((person,), laser=LaserSpec()), 16.0, from_dict({}), seed=3)
    labels = []
    for k, (truth, res) in enumerate(hist):
        if k < 30 or not truth:
            continue
        (p,) = truth
        est = res.estimates
        assert len(est) == 1, (k, est.m[:, :2])
        assert np.linalg.norm(est.m[0, :2] - p.centre) < 0.3, k
        labels.append(int(est.label[0]))
    assert len(labels) > 100 and len(set(labels)) == 1
    # standing from 6 s to 12 s: all of its returns reached the filter
    assert all(res.diagnostics['background_dropped'] == 0 for _, res in hist[60:120])


def test_object_that_appears_and_never_moves_in_open_space_is_learned():
    """The contrast: a track that never moved protects nothing on free beams (objects
    off; with them the box is tracked for object_time first)."""
    box = SimObject((5.0, 1.0), a=0.3, b=0.3, t_start=3.0, kind='box')
    hist = run(Scene((box,), laser=LaserSpec()), 10.0, from_dict(NO_OBJECTS), seed=4)
    assert all(len(res.estimates) == 0 for _, res in hist[60:]), \
        [len(res.estimates) for _, res in hist[30:]]
    assert all(res.diagnostics['background_dropped'] > 0 for _, res in hist[60:])


def _report(record, x, detections=5, semi=None):
    """The report ``record`` after label 7 is extracted at (x, 0) with ``detections``
    returns (and a semi-major axis ``semi``, 0.1 m semi-minor, if given)."""
    est = estimates([7], [[x, 0.0]])
    est.num_detections[:] = detections
    if semi is not None:
        est.X[:] = np.diag([semi ** 2, 0.01])
    return record_reports(record, est)


def test_travel_that_protects_counts_only_scans_with_returns():
    """A label coasting on its predicted velocity has not moved: its drift is not travel."""
    state = _report(TrackRecord(), 0.0, 5)
    for k in range(1, 11):                               # drifts 1 m with no returns
        state = _report(state, 0.1 * k, 0)
    assert state.reported_scans[0] == 11 and state.reported_hits[0] == 1
    scans_alone = from_dict({'extraction': {'confirm_detections': 0}}).extraction
    assert state.confirmed_travel(np.array([7, 8]), scans_alone).tolist() == [0.0, -1.0]
    # returns must have updated it in confirm_detections of its scans: one is not enough
    two = from_dict({'extraction': {'confirm_detections': 2}}).extraction
    assert state.confirmed_travel(np.array([7]), two).tolist() == [-1.0]
    state = _report(state, 1.2, 3)                        # seen again 1.2 m away
    assert np.allclose(state.confirmed_travel(np.array([7]), two), 1.2)
    not_yet = from_dict({'extraction': {'confirm_scans': 13}}).extraction
    assert state.confirmed_travel(np.array([7]), not_yet).tolist() == [-1.0]  # not 13 in a row
    state = _report(state, 0.3, 3)                        # and back: the farthest counts
    assert np.allclose(state.confirmed_travel(np.array([7]), two), 1.2)


def test_travel_is_counted_beyond_the_first_extent():
    """
    A static object whose returns are learned one side after the other sees its centre
    shift by up to its own size (MiR furniture: 0.55 m in 1.2 s): that is not travel. Travel
    counts beyond the semi-major axis the label was first reported with.
    """
    ex = from_dict({'extraction': {'confirm_detections': 0}}).extraction
    state = _report(TrackRecord(), 0.0, semi=0.5)
    for i, x in enumerate(np.linspace(0.05, 0.55, 11)):  # the centre creeps 0.55 m
        state = _report(state, x, semi=0.3)                # while the extent shrinks
        if i == 3:                                         # 0.2 m from where it began
            # within its first extent: no travel, 0 and not a shortfall (a moved_distance
            # of 0 counts every confirmed label as moved)
            assert state.confirmed_travel(np.array([7]), ex).tolist() == [0.0]
    assert np.allclose(state.confirmed_travel(np.array([7]), ex), 0.05)
    state = _report(state, 1.2, semi=0.3)                  # then it really goes
    assert np.allclose(state.confirmed_travel(np.array([7]), ex), 0.7)


def test_a_beam_flipping_between_two_ranges_learns_both():
    """
    The edge of a post: the beam returns the post (1.9 m) or the wall (4.9 m), in turn,
    from start-up, with no background known. Both ranges age as candidates; the first to
    have been returned for confirm_time becomes the background, the other a second range
    (each kept one scan at a time, a single candidate restarted at every flip and never
    got there). A farther range that turns up while the background is still returned is
    a second range too, not a replacement of the background.
    """
    cfg = from_dict({}).background
    no = np.zeros(3, bool)
    state, keep = _empty_then([1.9, 4.9] * 11, cfg, no)    # the 11th return of each
    assert not keep.any()
    assert np.allclose(state.background, 1.9) and np.allclose(state.second, 4.9)
    state, keep = _empty_then([1.9, 4.9] * 11 + [1.9, 4.9], cfg, no)
    assert not keep.any() and not state.learned.any()
    # known background 1.9 m, then 4.9 m in every other scan: a second range
    state, keep = _empty_then([1.9] * 12 + [4.9, 1.9] * 10 + [4.9], cfg, no)
    assert not keep.any() and state.learned.all()
    assert np.allclose(state.background, 1.9) and np.allclose(state.second, 4.9)



def test_a_range_interrupted_once_by_another_keeps_its_count():
    """
    A beam with nothing known returns the wall (4 m), once something passing (2.5 m) in
    between: the wall keeps the returns it had counted (it is the beam's other recent
    range meanwhile) and is learned at its 11th return, as without the interruption.
    """
    cfg = from_dict({}).background                      # confirm_time 1 s
    no = np.zeros(3, bool)
    seq = [4.0] * 6 + [2.5] + [4.0] * 5                 # the wall's 11th return last
    state, keep = _empty_then(seq[:-1], cfg, no)
    assert keep.all() and np.isnan(state.background).all()
    state, keep = _empty_then(seq, cfg, no)
    assert not keep.any() and state.learned.all() and np.allclose(state.background, 4.0)


def test_a_farther_range_replaces_the_background_only_when_the_background_has_gone():
    """
    Known background 2 m, then 4 m for confirm_time (11 returns). When the 2 m was
    returned within confirm_time of that (0.8 s before, between the 4 m returns), the
    beam flips between the two: 4 m becomes its second range and 2 m stays. When it was
    last returned 1.1 s before, 2 m has gone and 4 m replaces it.
    """
    cfg = from_dict({}).background
    no = np.zeros(3, bool)
    known = [2.0] * 12
    state, keep = _empty_then(known + [4.0] * 3 + [2.0] + [4.0] * 8, cfg, no)
    assert not keep.any() and state.learned.all()
    assert np.allclose(state.background, 2.0) and np.allclose(state.second, 4.0)
    state, keep = _empty_then(known + [4.0] * 11, cfg, no)
    assert not keep.any() and state.learned.all()
    assert np.allclose(state.background, 4.0) and np.isnan(state.second).all()


def test_the_second_range_is_refined_as_the_first_and_the_first_ages_meanwhile():
    """
    A post (1 m) learned as the beam's second range in front of its wall (4 m), then
    returned alone for 0.5 s at ranges that wander within the margin: the second range
    is the exponential smoothing of those returns (gain dt / learn_time; oracle: the
    loop), the wall's range stays, and the time since the wall was returned counts on
    (the post's returns are not the wall's).
    """
    cfg = from_dict({'background': {'forget_time': 5.0}}).background
    no = np.zeros(3, bool)
    post = [4.0] * 12 + [1.0, 4.0] * 10 + [1.0]
    state, _ = _empty_then(post, cfg, no)
    assert np.allclose(state.second, 1.0) and np.allclose(state.background_ago, 0.1)
    wander = np.float32([1.05, 0.97, 1.08, 1.02, 0.95])
    state, keep = _empty_then(post + list(wander), cfg, no)
    want = 1.0
    for r in wander:
        want += 0.1 / cfg.learn_time * (float(r) - want)
    assert not keep.any()
    np.testing.assert_allclose(state.second, want, rtol=1e-12)
    np.testing.assert_allclose(state.background, 4.0, rtol=1e-12)
    np.testing.assert_allclose(state.background_ago, 0.6)
    np.testing.assert_allclose(state.second_ago, 0.0)

def test_something_that_flickers_in_open_space_is_learned_not_kept_by_its_own_track():
    """
    A small static object in open space that returns in 60 % of scans (dark, at the edge
    of range): its beams go free while it is silent, a track forms on it, and that track
    has not moved, so it protects nothing there and the object is learned. (With any
    confirmed track protecting free beams, the track kept itself alive.) Objects off.
    """
    box = SimObject((8.6, 1.0), a=0.25, b=0.2, t_start=2.0, kind='box')
    rng = np.random.default_rng(11)
    cfg = from_dict(NO_OBJECTS)
    state = PipelineState.initial(cfg)
    tracked = []
    for k, (scan, truth) in enumerate(simulate(Scene((box,), laser=LaserSpec()), 12.0,
                                               seed=8)):
        if truth and rng.random() < 0.4:                   # a silent scan
            scan.ranges = np.full(len(scan.ranges), np.inf, dtype=np.float32)
        state, res = step(state, scan, cfg)
        d = np.linalg.norm(res.estimates.m[:, :2] - box.start, axis=1)
        tracked.append(bool(np.any(d < 0.5)))
    assert any(tracked[20:60])                             # it was tracked for a while
    assert not any(tracked[80:]), [k for k, t in enumerate(tracked) if t]


def test_known_background_a_protecting_track_holds_returns_in_front_and_behind():
    """
    A beam whose known background (2 m) has left returns 4 m for 3 s: learned after
    confirm_time, in the scan that completes it, unless a protecting track holds it; a
    nearer return (1 m for 3 s, nothing else in between) waits for forget_time either way.
    """
    cfg = from_dict({}).background                      # confirm_time 1 s, forget 30 s
    yes, no = np.ones(3, bool), np.zeros(3, bool)
    behind = [2.0] * 12 + [4.0] * 30
    state, keep = _empty_then(behind[:12 + 10], cfg, protected=no)
    assert keep.all() and not state.learned.any() and np.allclose(state.background, 2.0)
    state, keep = _empty_then(behind[:12 + 11], cfg, protected=no)
    assert not keep.any() and state.learned.all() and np.allclose(state.background, 4.0)
    state, keep = _empty_then(behind, cfg, protected=no)
    assert not keep.any() and not state.learned.any()   # learned once, then background
    state, keep = _empty_then(behind, cfg, protected=yes)
    assert keep.all() and np.allclose(state.background, 2.0)
    for prot in (no, yes):
        state, keep = _empty_then([2.0] * 12 + [1.0] * 30, cfg, prot)
        assert keep.all() and np.allclose(state.background, 2.0)
        assert np.isnan(state.second).all()


def test_thin_object_seen_in_some_scans_becomes_a_second_background_range():
    """
    A post that the beam hits in every other scan, the wall (4 m) returned in between:
    once the post's returns add up to confirm_time (11 of them: the first starts the
    count at 0, each later one adds a scan period) its range is a second background
    range and both are dropped. Not seen for forget_time, it is
    forgotten. Something that blocks the wall in every scan (a person standing) is not
    such a post: it waits for forget_time.
    """
    cfg = from_dict({'background': {'forget_time': 5.0}}).background
    no = np.zeros(3, bool)
    post = [4.0] * 12 + [1.0, 4.0] * 10 + [1.0]         # the post's 11th return last
    state, keep = _empty_then(post[:-2], cfg, no)      # the 10th: still foreground
    assert keep.all() and np.isnan(state.second).all()
    state, keep = _empty_then(post, cfg, no)
    assert not keep.any() and state.learned.all()
    assert np.allclose(state.second, 1.0) and np.allclose(state.background, 4.0)
    state, keep = _empty_then(post + [4.0, 1.0], cfg, no)
    assert not keep.any() and not state.learned.any()  # both ranges are background
    state, keep = _empty_then(post + [4.0] * 51 + [1.0], cfg, no)
    assert keep.all() and np.isnan(state.second).all()  # forgotten after 5 s unseen
    # blocking the wall in every scan for 3 s: not learned (forget_time is 5 s)
    state, keep = _empty_then([4.0] * 12 + [1.0] * 30, cfg, no)
    assert keep.all() and np.isnan(state.second).all()



def chair_reveals_box():
    """A chair 1.5 m away until 4 s, in front of a box 3.5 m away and a wall at 8 m."""
    return Scene((SimObject((1.5, 0.0), a=0.3, b=0.3, kind='chair', t_end=4.0),
                  SimObject((3.5, 0.0), a=0.3, b=0.3, kind='box')),
                 walls=(((8.0, -5.0), (8.0, 5.0)),), laser=LaserSpec())

def test_static_object_revealed_behind_a_learned_one_is_learned_and_its_track_dropped():
    """
    Something stands 1.5 m away at start-up and is learned; it leaves at 4 s and reveals a
    box 3.5 m away (the MiR recording's furniture behind what stood by the robot). The box
    is tracked as a new static object, then learned as background about confirm_time
    after it appeared; its track is dropped in that scan (``absorbed``) instead of
    coasting, and nothing is reported from 6.5 s on (objects off).
    """
    hist = run(chair_reveals_box(), 9.0, from_dict(NO_OBJECTS), seed=5)
    shown = [k for k, (_, res) in enumerate(hist)
             if len(res.estimates) and np.linalg.norm(res.estimates.m[:, :2] - (3.5, 0.0),
                                                      axis=1).min() < 0.5]
    assert shown and 40 <= shown[0] < 50              # tracked once revealed
    absorbed = [k for k, (_, res) in enumerate(hist) if res.diagnostics['absorbed']]
    assert absorbed and shown[-1] < absorbed[0] < 65    # not reported once learned
    assert all(len(res.estimates) == 0 for _, res in hist[65:]), \
        [len(res.estimates) for _, res in hist[40:]]
    # a dropped track's weight (about one object) leaves the expected count with it
    for k in absorbed:
        gone = hist[k][1].diagnostics['absorbed']
        assert hist[k][1].expected_count < hist[k - 1][1].expected_count - 0.8 * gone, k


@pytest.mark.slow
def test_static_object_in_front_of_the_wall_is_learned_after_forget_time_though_tracked():
    """
    A box put down 4 m away in front of the wall at 3 s is tracked, and learned as
    background once its returns add up to forget_time (3 s here): a track that never
    moved protects nothing (a chair moved in). The person who walks in and stops for
    6 s in front of the same wall is held by its moving track and stays tracked (objects
    off).
    """
    wall = (((8.0, -5.0), (8.0, 5.0)),)
    cfg = from_dict({'background': {'forget_time': 3.0, 'object_size': 0.0}})
    box = SimObject((4.0, 1.0), a=0.3, b=0.3, kind='box', t_start=3.0)
    hist = run(Scene((box,), walls=wall, laser=LaserSpec()), 9.0, cfg, seed=7)
    counts = [len(res.estimates) for _, res in hist]
    assert all(n == 1 for n in counts[36:60]), counts          # tracked meanwhile
    assert all(n == 0 for n in counts[66:]), counts            # learned by 6.6 s
    assert any(res.diagnostics['absorbed'] for _, res in hist[60:66])
    person = SimObject((6.0, 3.0), (-0.5, -0.5), t_start=2.0, stops=((4.0, 10.0),))
    hist = run(Scene((person,), walls=wall, laser=LaserSpec()), 11.0, cfg, seed=8)
    labels = set()
    for k, (truth, res) in enumerate(hist[30:105], start=30):
        (p,) = truth
        assert len(res.estimates) == 1, (k, res.estimates.m[:, :2])
        assert np.linalg.norm(res.estimates.m[0, :2] - p.centre) < 0.3, k
        labels.add(int(res.estimates.label[0]))
    assert len(labels) == 1


@pytest.mark.slow
def test_a_person_hidden_for_a_few_scans_while_standing_still_stays_protected():
    """
    A walker who stops in front of the wall, then is hidden for half a second (their label
    not reported in those scans, which restarts its report record and travel), is still
    held by its track: it had moved while it lived. Before, the restarted record counted
    no travel and the person was learned after forget_time (3 s here), at 9.6 s.
    """
    wall = (((8.0, -5.0), (8.0, 5.0)),)
    cfg = from_dict({'background': {'forget_time': 3.0}})
    person = SimObject((6.0, 3.0), (-0.5, -0.5), t_start=2.0, stops=((4.0, 14.0),))
    state = PipelineState.initial(cfg)
    counts, labels = [], set()
    for k, (scan, truth) in enumerate(simulate(Scene((person,), walls=wall, laser=LaserSpec()),
                                               14.0, seed=8)):
        if 60 <= k <= 64:                          # every return of the person lost
            scan = replace(scan, ranges=np.where(np.asarray(scan.ranges) < 7.0, np.inf,
                                                 scan.ranges))
        state, res = step(state, scan, cfg)
        counts.append(len(res.estimates))
        if k >= 30 and len(res.estimates):
            (p,) = truth
            assert np.linalg.norm(res.estimates.m[0, :2] - p.centre) < 0.3, k
            labels.add(int(res.estimates.label[0]))
    assert all(n == 0 for n in counts[62:66]), counts       # the label was not reported
    assert all(n == 1 for n in counts[70:]), counts         # and is again, to the end
    assert all(n == 1 for n in counts[30:62]), counts
    assert len(labels) == 1


def _fan(ranges_per_scan, cfg, n_beams=31, tracked=None, range_max=LaserSpec.range_max):
    """Feed whole scans of ranges (0.35 deg apart) with nothing protected (and the beams
    ``tracked`` near a reported track); the keep-masks over the beams (True: the beam's
    return reached the filter)."""
    spec = LaserSpec(angle_min=-0.0925, angle_max=0.0925, n_beams=n_beams,
                     range_max=range_max)
    (scan, _), = simulate(Scene((), laser=spec), 0.1, seed=0)
    state, kept = None, []
    for ranges in ranges_per_scan:
        scan.ranges = np.asarray(ranges, dtype=np.float32)
        sp = scan_to_points(scan)
        state, keep = update_background(state, sp, 0.1, cfg, np.zeros(n_beams, bool),
                                        tracked)
        beam_kept = np.zeros(n_beams, bool)
        beam_kept[sp.beam[keep]] = True
        kept.append(beam_kept)
    return state, kept


def _sparkle(ranges_of, n_scans, cfg, n_beams=31, seed=0, otherwise=np.inf, first=0):
    """
    Beams 0.35 deg apart (3 cm at 5 m) that return ``otherwise`` (default: nothing) in
    the ``first`` scans, and then each ``ranges_of(beam)`` in a random fifth of the scans
    and ``otherwise`` in the others (fed by :func:`_fan`); the keep-mask of every scan's
    ``ranges_of`` returns.
    """
    rng = np.random.default_rng(seed)
    target = np.array([ranges_of(b) for b in range(n_beams)])
    hits = [(rng.random(n_beams) < 0.2) & (k >= first) for k in range(n_scans)]
    state, kept = _fan([np.where(hit, target, otherwise) for hit in hits], cfg, n_beams)
    return state, [k[hit] for k, hit in zip(kept, hits)]


def test_a_surface_that_sparkles_over_the_beams_is_learned_from_all_of_them():
    """
    A wall at the edge of range, returned by each beam in a fifth of the scans only (the
    leg_tracker demo's far spots): a beam that returned nothing ages its candidate when a
    neighbour within ``margin`` across returned that range, so the wall is learned once it
    has been returned somewhere near each beam for confirm_time, not after 10 returns of
    each beam (some 50 scans), and its returns stop reaching the filter.
    """
    cfg = from_dict({}).background                  # margin 0.15 m: 4 beams at 5 m
    state, kept = _sparkle(lambda b: 5.0, 60, cfg)
    late = np.concatenate(kept[25:])
    assert np.mean(late) < 0.05, np.mean(late)
    assert np.isfinite(state.background).mean() > 0.9
    # each beam alone: far fewer of its returns are background by then
    lone = from_dict({'background': {'margin': 0.005}}).background   # no neighbour within
    _, kept = _sparkle(lambda b: 5.0, 60, lone)
    assert np.mean(np.concatenate(kept[25:40])) > 0.5
    # neighbours returning other ranges age nothing: a staircase, 0.2 m a beam, is learned
    # beam by beam
    _, kept = _sparkle(lambda b: 3.0 + 0.2 * b, 60, cfg)
    assert np.mean(np.concatenate(kept[25:40])) > 0.5


def test_a_gap_that_shows_the_wall_now_and_then_is_learned_from_all_its_beams():
    """
    The same through a gap: each beam returns its known background (2.2 m) and in a
    fifth of the scans the wall behind (4.9 m, obstacle_detector's spot). A beam that
    returned its background ages its candidate when a neighbour returned it, and the
    wall becomes every beam's second range.
    """
    cfg = from_dict({}).background
    state, kept = _sparkle(lambda b: 4.9, 75, cfg, otherwise=2.2, first=15)
    assert np.allclose(state.background, 2.2, atol=0.01)
    late = np.concatenate(kept[45:])
    assert len(late) > 100 and np.mean(late) < 0.05, np.mean(late)   # the wall's returns
    assert np.isfinite(state.second).mean() > 0.9
    lone = from_dict({'background': {'margin': 0.005}}).background
    _, kept = _sparkle(lambda b: 4.9, 75, lone, otherwise=2.2, first=15)
    assert np.mean(np.concatenate(kept[45:60])) > 0.5


def test_a_return_thinner_than_the_beam_spacing_in_front_of_the_wall_is_learned_when_ripe():
    """
    A wall 4 m away, known; then one beam returns 3.5 m in every scan (a thin pole, or a
    mixed return at an edge: positive_1's spot 2.9 m to the right, reported for 193
    scans) while its neighbours, 2 cm apart there, return the wall. Nothing a person
    makes is that thin, so it is learned once ripe (confirm_time), not after
    forget_time. Something 9 beams wide (20 cm) at the same range waits forget_time.
    """
    cfg = from_dict({}).background                  # confirm 1 s, forget 30 s
    wall = np.full(31, 4.0)
    pole, box = wall.copy(), wall.copy()
    pole[15] = 3.5
    box[11:20] = 3.5
    state, kept = _fan([wall] * 15 + [pole] * 30, cfg)
    assert not any(k[15] for k in kept[27:])         # learned by the 12th scan of it
    assert kept[16][15]                               # but not at once
    assert state.background[15] == pytest.approx(3.5, abs=0.01)
    _, kept = _fan([wall] * 15 + [box] * 30, cfg)
    assert all(k[11:20].all() for k in kept[16:])     # 3 s in front of the wall: kept
    # a thin return that flips with the wall behind it is the beam's second range, the
    # wall stays its background (no wall returns let through meanwhile)
    state, kept = _fan([wall] * 15 + [pole, wall] * 15, cfg)
    assert state.background[15] == pytest.approx(4.0, abs=0.01)
    assert state.second[15] == pytest.approx(3.5, abs=0.01)
    assert not any(k[15] for k in kept[36:])


def test_beams_farther_apart_than_margin_across_leave_a_thin_return_thin():
    """
    Two poles two beams apart in front of the wall, with a margin (3 cm) that one beam's
    spacing at 3.5 m (2.2 cm) is within and two beams' (4.3 cm) are not: the beam between
    returns the wall, and the other pole is no neighbour, so each return is thinner than
    the beam spacing and learned once ripe, as one pole alone is.
    """
    cfg = from_dict({'background': {'margin': 0.03}}).background
    wall = np.full(31, 4.0)
    poles = wall.copy()
    poles[[15, 17]] = 3.5
    state, kept = _fan([wall] * 15 + [poles] * 30, cfg)
    assert kept[16][15] and kept[16][17]              # not at once
    assert not any(k[15] or k[17] for k in kept[27:])  # learned by the 12th scan of them
    assert state.background[[15, 17]] == pytest.approx([3.5, 3.5], abs=0.01)


def test_a_full_turn_learns_the_same_wherever_its_seam_falls():
    """
    A 360 degree scanner: a beam's neighbours across the seam (the last beam and the
    first) count as neighbours. Oracle: the same scans with every range moved by half a
    turn of beams learn the same background, moved the same way. The scene: a wall at
    6 m, and across the seam a surface at 4 m that sparkles (each beam returns it in
    some scans only, as at the edge of range), which neighbours' returns ripen.
    """
    from extended_tracker.sensing.scan import Header, ScanData, Stamp

    cfg = from_dict({}).background
    rng = np.random.default_rng(3)
    n = 360
    seq = []
    for _ in range(25):
        r = np.full(n, 6.0)
        near = (np.arange(n) >= 350) | (np.arange(n) < 10)        # across the seam
        r[near] = np.where(rng.random(near.sum()) < 0.3, 4.0, np.inf)
        seq.append(r)

    def learn(shift):
        state = None
        for r in seq:
            scan = ScanData(Header(Stamp(1, 0), 'laser'), 0.0, 2 * np.pi * (n - 1) / n,
                            2 * np.pi / n, 0.05, 13.0, np.roll(r, shift))
            sp = scan_to_points(scan)
            assert sp.full_turn
            state, _ = update_background(state, sp, 0.1, cfg, np.zeros(n, bool))
        return state

    plain, turned = learn(0), learn(n // 2)
    for name in ('background', 'candidate', 'candidate_age', 'learned'):
        np.testing.assert_array_equal(np.roll(getattr(turned, name), -(n // 2)),
                                      getattr(plain, name), err_msg=name)
    seam = (np.arange(n) >= 350) | (np.arange(n) < 10)
    assert np.isfinite(plain.background[~seam]).all()           # the wall
    assert np.isfinite(plain.background[seam]).sum() >= 18      # the sparkling surface


def test_a_wall_hidden_since_start_up_is_learned_as_soon_as_it_is_revealed():
    """
    The bundled demo's wall: part of it is hidden from start-up by something that never
    holds still (a walker), and is revealed when the walker leaves. Its beams have no
    background and were never seen free; their returns continue a neighbour's learned
    wall (within ``margin``), so they are learned in the scan that reveals them, not
    tracked as an object for the confirm_time they would take to ripen. Something
    standing in front of the revealed wall (by more than ``margin``) is not: it does not
    continue the wall; nor are returns near a reported track (a person who stood from
    start-up, one leg learned: the other leg continues it).
    """
    cfg = from_dict({}).background                   # margin 0.15 m, confirm_time 1 s
    wall = np.full(31, 5.0)
    hidden = [np.where(np.arange(31) < 10, wall, 1.0 + 0.2 * k) for k in range(15)]
    state, kept = _fan(hidden + [wall] * 3, cfg)
    assert np.allclose(state.background[:10], 5.0)   # the part seen from start-up
    assert not kept[15].any()                        # revealed: learned at once
    assert np.allclose(state.background, 5.0, atol=0.01)
    # a person 0.4 m in front of the wall on the last beams when it is revealed
    person = np.where(np.arange(31) >= 21, 4.6, 5.0)
    state, kept = _fan(hidden + [person] * 3, cfg)
    assert not kept[15][:21].any() and kept[15][21:].all()
    assert np.isnan(state.background[21:]).all()
    # the revealed beams near a reported track ripen as any return does
    near = np.arange(31) >= 10
    state, kept = _fan(hidden + [wall] * 12, cfg, tracked=near)
    assert kept[15][10:].all() and not kept[-1][10:].any()
    # before this, the revealed wall waited out confirm_time like a new object
    state, kept = _fan(hidden + [wall] * 12, from_dict({'background': {'margin': 0.005}})
                       .background)
    assert kept[15][10:].all() and not kept[-1][10:].any()



def test_a_person_stepping_into_an_open_doorway_does_not_continue_the_wall():
    """
    A wall 5 m away with a doorway (beams 10-20 return nothing: out of range beyond it),
    those beams seen free. Then someone fills the doorway in line with the wall (5.05 m):
    their returns are within margin of the wall's range next to the door, but the beams
    were seen free, so they continue nothing (that is for beams never seen, a wall
    revealed): they reach the filter as any new return does until confirm_time.
    """
    cfg = from_dict({}).background
    door = np.full(31, 5.0)
    door[10:21] = np.inf
    person = door.copy()
    person[10:21] = 5.05
    state, kept = _fan([door] * 12 + [person] * 3, cfg)
    assert state.free[10:21].all() and np.isfinite(state.background[:10]).all()
    assert all(k[10:21].all() and not k[:10].any() and not k[21:].any() for k in kept[12:])
    assert np.isnan(state.background[10:21]).all()


def test_a_surface_fading_in_and_out_at_the_edge_of_range_continues_the_wall():
    """
    The leg_tracker demo's far wall: 5.45 m away, range 5.6 m. Beams 0-14 return it
    every scan; on beams 15-30 it fades: they return nothing for 1.5 s (seen free), then
    a few of them return it in one scan. Within the last 5 % of the range those returns
    continue the learned wall and are learned at once. The same geometry well within
    range is the open doorway above: a return there reaches the filter.
    """
    cfg = from_dict({}).background
    wall = np.where(np.arange(31) < 15, 5.45, np.inf)
    some = wall.copy()
    some[15:19] = 5.47
    for range_max in (5.6, 6.0):
        state, kept = _fan([wall] * 15 + [some], cfg, range_max=range_max)
        assert state.free[15:].all() and np.isfinite(state.background[:15]).all()
        assert not kept[-1][:15].any()
        if range_max == 5.6:                         # 5.47 m: in the last 5 % of 5.6 m
            assert not kept[-1][15:19].any() and np.isfinite(state.background[15:19]).all()
        else:
            assert kept[-1][15:19].all() and np.isnan(state.background[15:19]).all()


def test_a_scan_at_other_angles_takes_the_nearest_beams_background():
    """The background is per beam and re-mapped by angle when the beams change: a scan
    whose beams lie within half a spacing of the learned ones (a scanner turned by half a
    beam) takes their background; beams beyond what was learned (the field of view
    turned away by 31 beams) start unknown. The same angles again keep what was learned."""
    cfg = from_dict({}).background
    spec = LaserSpec(angle_min=-0.0925, angle_max=0.0925, n_beams=31)
    (scan, _), = simulate(Scene((), laser=spec), 0.1, seed=0)
    scan.ranges = np.full(31, 4.0, dtype=np.float32)
    none = np.zeros(31, bool)
    state = None
    for _ in range(11):
        state, keep = update_background(state, scan_to_points(scan), 0.1, cfg, none)
    assert not keep.any() and np.allclose(state.background, 4.0)
    same, keep = update_background(state, scan_to_points(scan), 0.1, cfg, none)
    assert not keep.any() and np.allclose(same.background, 4.0)
    half = replace(scan, angle_min=scan.angle_min + 0.5 * scan.angle_increment,
                   angle_max=scan.angle_max + 0.5 * scan.angle_increment)
    turned, keep = update_background(state, scan_to_points(half), 0.1, cfg, none)
    assert not keep.any() and np.allclose(turned.background, 4.0)
    away = replace(scan, angle_min=scan.angle_min + 31 * scan.angle_increment,
                   angle_max=scan.angle_max + 31 * scan.angle_increment)
    elsewhere, keep = update_background(state, scan_to_points(away), 0.1, cfg, none)
    assert keep.all() and np.isnan(elsewhere.background).all()


def _continues_ring_by_ring(r, b, which, reach, margin, wrap):
    """The plain reading of ``continues_surface``: one ring of neighbours a round, beam by beam."""
    from extended_tracker.sensing.background import NEIGHBOUR_BEAMS

    n = len(r)
    b = b.copy()
    out = np.zeros(n, bool)
    while True:
        new = []
        for i in np.nonzero(which & ~out)[0]:
            for off in range(-NEIGHBOUR_BEAMS, NEIGHBOUR_BEAMS + 1):
                j = i + off
                if wrap:
                    j %= n
                elif not 0 <= j < n:
                    continue
                if (off and np.isfinite(b[j]) and abs(r[i] - b[j]) <= margin
                        and r[i] <= reach[off + NEIGHBOUR_BEAMS]):
                    new.append(i)
                    break
        if not new:
            return out
        out[new] = True
        b[new] = r[new]


@pytest.mark.parametrize('seed', range(40))
def test_revealed_stretches_are_found_as_ring_by_ring(seed):
    """Runs taken whole give what finding one ring of neighbours a round gives."""
    from extended_tracker.sensing.background import continues_surface, NEIGHBOUR_BEAMS, reach_of

    rng = np.random.default_rng(seed)
    n = int(rng.integers(2, 60))
    # piecewise surfaces: steps of 0.05-0.4 m, some beams with nothing
    r = 3.0 + np.cumsum(rng.choice([0.0, 0.05, 0.1, 0.3, -0.3, 0.4], n))
    r[rng.random(n) < 0.1] = np.inf
    b = np.where(rng.random(n) < 0.3, r + rng.normal(0, 0.1, n), np.nan)
    which = np.isnan(b) & np.isfinite(r) & (rng.random(n) < 0.9)
    reach = reach_of(np.deg2rad(rng.choice([0.25, 0.5, 1.0, 3.0])), 0.15)
    if seed % 2 == 0:
        # about where beams one apart stop being within margin across: runs end there
        shift = 0.97 * reach[NEIGHBOUR_BEAMS + 1] - 3.0
        r, b = r + shift, b + shift
    for wrap in (False, True):
        got = continues_surface(r, b, which, reach, 0.15, wrap)
        assert np.array_equal(got, _continues_ring_by_ring(r, b, which, reach, 0.15, wrap))


@pytest.mark.parametrize('seed', range(10))
def test_beams_near_tracks_in_one_pass_as_with_the_plain_distance(seed):
    """``beams_near_tracks`` gives the beams near the guard tracks and near any track,
    each as the plain reading (``np.linalg.norm`` of every return to every centre against
    radius plus gate) gives them."""
    from extended_tracker.sensing.background import beams_near_tracks

    rng = np.random.default_rng(seed)
    (scan, _), = simulate(Scene((), walls=(((4.0, -6.0), (4.0, 6.0)),),
                                laser=LaserSpec(dropout=0.2)), 0.1, seed=seed)
    sp = scan_to_points(scan)
    k = int(rng.integers(0, 6))
    centres = np.column_stack([rng.uniform(3.0, 5.0, k), rng.uniform(-5.0, 5.0, k)])
    radius = rng.uniform(0.1, 0.8, k)
    guard = rng.random(k) < 0.5

    def plain(c, rad):
        out = np.zeros(len(sp.angles), bool)
        if len(c):
            d = np.linalg.norm(sp.points[:, None, :] - c[None], axis=2)
            out[sp.beam[(d <= rad + 0.5).any(axis=1)]] = True
        return out

    prot, near = beams_near_tracks(sp, centres, radius, 0.5, guard)
    assert np.array_equal(prot, plain(centres[guard], radius[guard]))
    assert np.array_equal(near, plain(centres, radius))


@pytest.mark.slow
def test_a_car_that_parks_is_learned_only_people_sized_tracks_protect():
    """A car drives in and parks: its track moved, but it is far larger than a person
    (``protect_semi_axis``), so its returns are learned like a wall's once it stands
    still, and nothing is reported from two seconds after it stopped. Were every moving
    track to protect its returns, the parked car would be tracked to the end."""
    car = SimObject((12.0, 3.0), (-2.0, 0.0), shape='rectangle', a=4.5, b=1.8, kind='car',
                    stops=((3.0, 60.0),))
    for semi, parked in ((0.6, 0), (100.0, 1)):
        cfg = from_dict({'background': {'protect_semi_axis': semi}})
        hist = run(Scene((car,), laser=LaserSpec()), 12.0, cfg, seed=2)
        assert any(len(res.estimates) for _, res in hist[20:30])       # tracked while driving
        assert all(len(res.estimates) >= parked for _, res in hist[50:]), semi
        if not parked:
            assert all(len(res.estimates) == 0 and res.diagnostics['background_dropped'] > 0
                       for _, res in hist[50:])


def test_the_region_birth_of_a_scan_is_never_absorbed():
    """
    A birth region on the box that the chair reveals: in the scans where the box's beams
    are learned and its tracks absorbed, the region's birth of that very scan is not among
    them (it is no track that stood on those returns), and is in the posterior (objects
    off; leg pairing off, which joins the box's first tracks into one, absorbed once).
    """
    cfg = from_dict({'birth': {'regions': [3.5, 0.0, 0.3]}, 'reduction': {'pair_scans': 0},
                     **NO_OBJECTS})
    state = PipelineState.initial(cfg)
    absorbed = 0
    for scan, _ in simulate(chair_reveals_box(), 6.0, seed=5):
        first_new = state.filter.next_label
        state, res = step(state, scan, cfg)
        if res.diagnostics['absorbed']:
            absorbed += 1
            assert first_new in state.filter.mixture.label
    assert absorbed >= 2


def _relaid(scan, kind):
    """``scan`` with another beam layout over the same field of view: two beams short,
    listed the other way round, or four times finer (the ranges of the nearest beam)."""
    import copy

    s = copy.deepcopy(scan)
    r = np.asarray(scan.ranges)
    if kind == 'two short':
        s.ranges = r[:-2].copy()
        s.angle_max = scan.angle_max - 2 * scan.angle_increment
    elif kind == 'reversed':
        s.ranges = r[::-1].copy()
        s.angle_min, s.angle_max = scan.angle_max, scan.angle_min
        s.angle_increment = -scan.angle_increment
    else:
        s.ranges = np.repeat(r, 4)[:4 * len(r) - 3].copy()
        s.angle_increment = scan.angle_increment / 4
    return s


@pytest.mark.parametrize('kind', ['two short', 'reversed', 'four times finer'])
def test_a_scan_with_another_beam_layout_keeps_the_learned_background(kind):
    """A driver that changes the beam count now and then: the scan is said
    (``scan_layout_changed``, with the counts), what was learned is re-mapped to its beams
    by angle, and the walls stay background: no track appears, the person keeps an id.
    (It used to throw the background away without a word: walls became tracks.)"""
    cfg = from_dict({})
    data = simulate(walls_scene(), 8.0, seed=0)
    state = PipelineState.initial(cfg)
    for scan, _ in data[:60]:
        state, res = step(state, scan, cfg)
    before = res.estimates.label.tolist()
    scan, truth = data[60]
    state, res = step(state, _relaid(scan, kind), cfg)
    assert res.event == 'scan_layout_changed'
    assert 'beams over' in res.error and f'learned on {len(scan.ranges)}' in res.error
    assert res.diagnostics['background_dropped'] > 0.8 * res.diagnostics['detections']
    labels = []
    for scan, _ in data[61:75]:
        state, res = step(state, scan, cfg)
        labels.append(res.estimates.label.tolist())
    assert all(lab == before for lab in labels), (before, labels)
