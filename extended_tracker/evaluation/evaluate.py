"""
Evaluation against ground truth: a replayed bag and its truth.json, or the scenario suite.

``extended-tracker evaluate OUTPUT_BAG --truth TRUTH [--plot PNG]`` scores a replay;
``extended-tracker results`` runs every scenario of the suite for CPHD and PHD, with
scan-shadow and constant p_D, and prints (or writes into the README) one table.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .. import stopping
from ..config import from_dict
from ..errors import BagError, ExtendedTrackerError
from ..frames.pose import Placement, Pose2
from ..pipeline import PipelineState, step
from ..sim import laser
from ..sim.drive import corridor_drive_scene
from ..sim.leg_scenes import at_leg_height, counting_scene, COUNTING_SECONDS
from ..sim.two_scanners import two_scanner_scans, two_scanner_scenes
from ..tracks.travel import Travel
from .metrics import score_sequence

GOSPA_C = 2.0          # m, cut-off
GOSPA_P = 2.0

# every scenario's config: the simulated laser puts its clutter returns on random beams at
# uniform ranges (sim.laser), and the filter is told so; their rate it learns (its
# model.clutter_rate stays the default)
SUITE_CONFIG = {'model': {'clutter_density': 'beam'}}

# name: (scene factory, seconds, seed, config overrides, what it shows); every scene runs
# with the defaults (and SUITE_CONFIG)
BODY_SCENARIOS = {
    'tutorial': (laser.tutorial_scene, 12.0, 1, {},
                 '180 deg / 0.5 deg / 13 m, four pedestrians, one standing from start-up, one '
                 'walking behind it and one in front of it'),
    'crossing': (laser.crossing_scene, 12.0, 2, {},
                 'three pedestrians crossing paths, passing 0.6-0.7 m apart'),
    'mixed_traffic': (laser.mixed_traffic_scene, 8.0, 3, {},
                      '270 deg / 0.25 deg / 30 m: a car, two bicycles, seven pedestrians, '
                      '3 clutter returns'),
    'crowd20': (lambda: laser.crowd_scene(20, seed=5, seconds=10.0), 10.0, 4, {},
                'a crowd of 20, heavy occlusion'),
    'clutter': (laser.clutter_scene, 12.0, 5, {},
                'the tutorial people with 15 clutter returns per scan'),
    'walls': (laser.walls_scene, 20.0, 6, {},
              'a room with walls and furniture; a person walks in and stands 10 s'),
    'corridor_drive': (corridor_drive_scene, 20.0, 7, {},
                       'the scanner on a robot driving an L-shaped corridor at 0.6-0.8 m/s '
                       'and turning into the side corridor (270 deg / 0.5 deg / 13 m), '
                       'tracked in odom: people walking both ways, one who walks to the '
                       'wall and stands there, one overtaking the robot'),
    'two_scanners': (two_scanner_scenes, 12.0, 8, {},
                     'two 270 deg / 0.5 deg / 12 m scanners on opposite corners of a robot, '
                     '0.05 s out of step, one tracker in base_link; a person circles the '
                     'robot through both fields of view, two walk past (scored over the '
                     'whole room, which both ranges cover)'),
}
COUNTING = (1, 2, 4, 8, 15)     # people of the people-counting scenes


def _leg_twin(factory):
    return lambda: at_leg_height(factory())


def _counting(n):
    return lambda: counting_scene(n, seed=n)


SCENARIOS = {}
for _name, (_factory, _seconds, _seed, _over, _) in BODY_SCENARIOS.items():
    SCENARIOS[_name] = BODY_SCENARIOS[_name]
    SCENARIOS[_name + '_legs'] = (_leg_twin(_factory), _seconds, _seed, _over,
                                  f'`{_name}` at leg height: each walker two swinging legs')
for _n in COUNTING:
    SCENARIOS[f'counting_{_n}'] = (
        _counting(_n), COUNTING_SECONDS, 20 + _n, {},
        f'{_n} {"person" if _n == 1 else "people"} walking past a stationary 180 deg / '
        '0.35 deg / 10 m scanner at leg height, some side by side')
VARIANTS = {
    'CPHD, scan shadow': {'model': {'mode': 'cphd'}, 'detection': {'model': 'scan_shadow'}},
    'CPHD, constant p_D': {'model': {'mode': 'cphd'}, 'detection': {'model': 'constant'}},
    'PHD, scan shadow': {'model': {'mode': 'phd'}, 'detection': {'model': 'scan_shadow'}},
    'PHD, constant p_D': {'model': {'mode': 'phd'}, 'detection': {'model': 'constant'}},
}


def merge_overrides(a: dict, b: dict) -> dict:
    out = {k: dict(v) for k, v in a.items()}
    for k, v in b.items():
        out.setdefault(k, {}).update(v)
    return out


VIEW_EDGE = 1e-9       # rad and m: points this close to the region's edge count as in it


def in_view(xy, view) -> np.ndarray:
    """
    Which of the points ``xy`` (k, 2) lie in the region a scanner covers, ``view =
    (angle_min, angle_max, range_max)``: its sector out to its range (all of them when
    ``view`` is None). The region the scores are taken over.

    Points on the edge are in, within ``VIEW_EDGE``: the simulator walks objects along
    the sector's edges (through (-8, 8) for a 270 deg scanner), and without the margin
    their membership would rest on the last bit of ``arctan2``.
    """
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if view is None:
        return np.ones(len(xy), dtype=bool)
    if len(view) == 4:                   # a scanner posed in the fixed frame the points are in
        xy = view[3].to_inner(xy)
        view = view[:3]
    a0, a1, range_max = (float(v) for v in view)
    lo, width = min(a0, a1), abs(a1 - a0)             # angle_increment may be negative
    near = np.hypot(xy[:, 0], xy[:, 1]) <= range_max + VIEW_EDGE
    if width >= 2.0 * np.pi:
        return near
    # measured from VIEW_EDGE before the sector's start, so that a point just before it
    # does not wrap round to 2 pi
    bearing = np.mod(np.arctan2(xy[:, 1], xy[:, 0]) - (lo - VIEW_EDGE), 2.0 * np.pi)
    return near & (bearing <= width + 2.0 * VIEW_EDGE)


def view_of(scan, pose=None):
    """The region a LaserScan covers, for :func:`in_view`; with the scanner's ``pose`` in
    a fixed frame, the region there."""
    view = (scan.angle_min, scan.angle_max, scan.range_max)
    return view if pose is None else view + (pose,)


def objects_in_view(objects, view=None) -> list:
    """The objects whose centre lies in ``view`` (see :func:`in_view`), in their order."""
    objs = list(objects)
    keep = in_view([o.centre for o in objs], view)
    return [o for o, k in zip(objs, keep) if k]


def truth_of(objects, view=None):
    """
    Truth set of one scan: the objects whose centre lies in ``view`` (see
    :func:`in_view`), hidden ones included (a tracker should keep them).
    """
    objs = objects_in_view(objects, view)
    return ([o.id for o in objs], np.array([o.centre for o in objs]).reshape(-1, 2),
            np.array([o.extent for o in objs]).reshape(-1, 2, 2))


def hidden_of(objects, view=None) -> np.ndarray:
    """Which objects of :func:`truth_of`'s set (same order) no beam reaches."""
    return np.array([o.visible_beams == 0 for o in objects_in_view(objects, view)],
                    dtype=bool)


def run_scenario(name: str, variant: dict, travel: Travel | None = None):
    """
    Run one scenario with a config variant; return the TrackScore and per-scan GOSPA
    (and add every scan's estimates to ``travel``, when given).

    Scored over the region the scanner covers: objects outside its sector or beyond its
    range are not in the truth, and estimates there are not scored (a track may coast a
    little past the range it left by). A scene of several scanners is scored over all of
    it.
    """
    factory, seconds, seed, overrides, _ = SCENARIOS[name]
    cfg = from_dict(merge_overrides(merge_overrides(SUITE_CONFIG, overrides), variant))
    state = PipelineState.initial(cfg)
    truth_seq, est_seq, hidden_seq = [], [], []
    scenes = factory()
    several = isinstance(scenes, list)          # one scene per scanner: the whole room
    for scan, objs, place in scenario_scans(scenes, seconds, seed):
        stopping.check()                 # a lost Ctrl-C: before `results` writes README
        state, res = step(state, scan, cfg, place=place)
        if travel is not None:
            travel.add(res.estimates)
        view = None if several else view_of(scan, place and place.pose)
        objs = objects_in_view(objs, view)             # once, for the truth and its hidden
        truth_seq.append(truth_of(objs))
        hidden_seq.append(hidden_of(objs))
        e = res.estimates
        shown = in_view(e.m[:, :2], view)
        est_seq.append((e.label[shown].tolist(), e.m[shown, :2], e.X[shown]))
    return score_sequence(truth_seq, est_seq, GOSPA_C, GOSPA_P, hidden_seq)


def scenario_scans(scenes, seconds: float, seed: int):
    """``(scan, truth, place)`` of a scene (``place`` None for a scanner standing in the
    walls' frame), or of a list of scenes (one per scanner) merged in stamp order."""
    if isinstance(scenes, list):
        yield from two_scanner_scans(seconds, seed, scenes)
        return
    for k, (scan, objs) in enumerate(laser.simulate(scenes, seconds, seed=seed)):
        pose = scenes.pose(k / scenes.laser.rate_hz + scenes.laser.phase)
        yield scan, objs, None if pose is None else Placement(scenes.drive.fixed_frame, pose)


def results_table() -> str:
    """The README table: one row per scenario and variant."""
    lines = ['| scenario | filter, p_D | mean GOSPA (m) | missed | false | card. error '
             '| id switches | fragmentations | hidden kept |',
             '|---|---|---|---|---|---|---|---|---|']
    for name in SCENARIOS:
        for vname, variant in VARIANTS.items():
            s, _ = run_scenario(name, variant)
            lines.append(f'| {name} | {vname} | {s.gospa_mean:.2f} | {s.missed_mean:.2f} | '
                         f'{s.false_mean:.2f} | {s.cardinality_error:.2f} | {s.id_switches} | '
                         f'{s.fragmentations} | {hidden_kept(s)} |')
    return '\n'.join(lines)


def moved_ids(name: str) -> int:
    """Distinct ids of a scenario run with the defaults that moved more than 1 m from
    where they were first shown (the count `extended-tracker real` gives)."""
    travel = Travel()
    run_scenario(name, {}, travel)
    return travel.moved()


def counting_table() -> str:
    """People walking past and the distinct ids that moved, per people-counting scene."""
    lines = ['| scenario | people | ids that moved over 1 m |', '|---|---|---|']
    lines += [f'| counting_{n} | {n} | {moved_ids(f"counting_{n}")} |' for n in COUNTING]
    return '\n'.join(lines)


def hidden_kept(score) -> str:
    """``kept / hidden`` object-scans, ``-`` where nothing was hidden."""
    return f'{score.hidden_kept} / {score.hidden}' if score.hidden else '-'


def scenario_notes() -> str:
    return '\n'.join(f'- `{k}`: {v[4]} ({v[1]:g} s, seed {v[2]})' for k, v in SCENARIOS.items())


def write_readme_results(readme: Path) -> None:
    """Replace the results section between its markers (in ``doc/results.md``)."""
    begin, end = '<!-- results:begin -->', '<!-- results:end -->'
    try:
        text = readme.read_text()
    except OSError as err:
        raise ExtendedTrackerError(f'cannot read {readme}: {err}') from err
    if begin not in text or end not in text:
        raise ExtendedTrackerError(f'{readme} has no {begin} ... {end} section')
    body = (f'{begin}\nMean GOSPA (c = {GOSPA_C:g} m, p = {GOSPA_P:g}, alpha = 2, '
            'Gaussian-Wasserstein distance between ellipses) with its missed and false parts, '
            'the mean |estimated - true| count (card. error), and hidden kept k / n: of the n '
            'object-scans no beam reached, the k that kept an estimate. Scored over the '
            'scanner\'s sector and range. Clutter falls on random beams '
            '(`model.clutter_density: beam`), as the simulated laser makes it.\n\n'
            f'{scenario_notes()}\n\n{results_table()}\n\nPeople counting (the defaults, '
            'CPHD with scan shadows; the count `make real` gives for recordings):\n\n'
            f'{counting_table()}\n{end}')
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    readme.write_text(head + body + tail)


def evaluate_bag(output_bag, truth_path, plot=None):
    """
    Score the ``/tracks`` of a replayed bag against a simulator ``truth.json``, over the
    region the scanner covers when the truth file gives it (``info.view``, see
    :func:`in_view`), as :func:`run_scenario` does. ``plot`` is checked as
    :func:`imagefile.image_path` checks it before the bag is read.
    """
    from rosbags.rosbag2 import Reader

    from ..bag.bagio import message_typestore

    by_stamp, view, digest, beams_known, poses = _read_truth(truth_path)
    if plot:
        from ..report.imagefile import image_path

        plot = image_path(plot)
    store = message_typestore()
    truth_seq, est_seq, stamps, counts, hidden_seq = [], [], [], [], []
    try:
        reader = Reader(output_bag)
    except Exception as err:  # rosbags raises several unrelated types for broken bags
        msg = f'cannot read {output_bag}: {err}'
        raise BagError(msg) from err
    with reader:
        conns = [c for c in reader.connections if c.topic == '/tracks']
        if not conns:
            raise BagError(f'{output_bag} has no /tracks topic')
        if digest is not None:
            _check_scans(reader, store, digest, output_bag, truth_path)
        for conn, t, raw in reader.messages(connections=conns):
            msg = store.deserialize_cdr(raw, conn.msgtype)
            ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            if ns not in by_stamp:
                continue
            scan_view = view if ns not in poses else tuple(view) + (Pose2(*poses[ns]),)
            objs, truth, est = _scan_sets(by_stamp[ns], msg.objects, scan_view)
            if beams_known:
                hidden_seq.append(np.array([o['visible_beams'] == 0 for o in objs], dtype=bool))
            truth_seq.append(truth)
            est_seq.append(est)
            stamps.append(ns)
            counts.append((len(objs), len(est[0])))
    if not stamps:
        raise BagError('no /tracks message matches a truth stamp')
    score, per = score_sequence(truth_seq, est_seq, GOSPA_C, GOSPA_P,
                                hidden_seq if beams_known else None)
    if plot:
        _plot(plot, np.array(stamps), per, np.array(counts))
    return score, per, np.array(stamps)


def _read_truth(truth_path):
    """``(objects by stamp, view, scan digest, whether hidden objects are known, scanner
    poses by stamp)`` of a truth file (poses where the scanner drives: the truth is in
    the fixed frame); BagError if it cannot be read."""
    try:
        truth = json.loads(Path(truth_path).read_text())
        by_stamp = {s['stamp_ns']: s['objects'] for s in truth['scans']}
        poses = {s['stamp_ns']: s['pose'] for s in truth['scans'] if 'pose' in s}
        view = truth.get('info', {}).get('view')
        digest = truth.get('info', {}).get('scan_digest')
        # which objects were hidden is known when every object says how many beams
        # reached it (an older truth file says it of none)
        beams_known = all('visible_beams' in o for objs in by_stamp.values() for o in objs)
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as err:
        msg = (f'cannot read the truth {truth_path} (a truth.json written by '
               f'extended-tracker simulate): {err!r}')
        raise BagError(msg) from err
    return by_stamp, view, digest, beams_known, poses


def _scan_sets(objs, objects, view):
    """The truth objects in view, and the truth and estimate sets of one scan (ids,
    centres, extents) from the truth objects and a message's ``objects``."""
    objs = [o for o, k in zip(objs, in_view([o['centre'] for o in objs], view)) if k]
    est_m = np.array([[o.position.x, o.position.y] for o in objects]).reshape(-1, 2)
    est = [o for o, k in zip(objects, in_view(est_m, view)) if k]
    truth = ([o['id'] for o in objs], np.array([o['centre'] for o in objs]).reshape(-1, 2),
             np.array([o['extent'] for o in objs]).reshape(-1, 2, 2))
    estimated = ([o.id for o in est],
                 np.array([[o.position.x, o.position.y] for o in est]).reshape(-1, 2),
                 np.array([np.asarray(o.extent).reshape(2, 2) for o in est]).reshape(-1, 2, 2))
    return objs, truth, estimated


def _check_scans(reader, store, digest, output_bag, truth_path) -> None:
    """
    Refuse a truth written for other scans than the replay's ``/scan`` holds: two
    simulations of the same rate share their stamps, so matching by stamp alone scores
    a replay against the wrong truth without a word.
    """
    import hashlib

    from ..sim.bag import scan_ranges_bytes

    h, n = hashlib.sha256(), 0
    conns = [c for c in reader.connections if c.topic == '/scan']
    for conn, _, raw in reader.messages(connections=conns):
        h.update(scan_ranges_bytes(store.deserialize_cdr(raw, conn.msgtype)))
        n += 1
    if h.hexdigest() != digest:
        raise BagError(f'{truth_path} is the truth of other scans than the {n} in '
                       f'{output_bag} (a truth.json of another simulation?): evaluate '
                       'the replay of the bag it was written with')


def _plot(path, stamps, per, counts):
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    t = (stamps - stamps[0]) * 1e-9
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(9, 6), sharex=True, dpi=110)
    a1.plot(t, [g.total for g in per], label='GOSPA')
    a1.plot(t, [np.sqrt(g.localisation) for g in per], label='localisation part^(1/2)')
    a1.set_ylabel('m')
    a1.legend()
    a2.step(t, counts[:, 0], where='post', label='true')
    a2.step(t, counts[:, 1], where='post', label='estimated')
    a2.set_ylabel('objects')
    a2.set_xlabel('time (s)')
    a2.legend()
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


__all__ = ['SCENARIOS', 'VARIANTS', 'evaluate_bag', 'hidden_of', 'results_table',
           'run_scenario', 'write_readme_results']
