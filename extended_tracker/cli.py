"""
``extended-tracker``: the user command line.

    extended-tracker replay INPUT --output OUTPUT [--scan-topic T] [--fixed-frame F]
                            [--config YAML | --preset P]
                            [--plot PNG]
    extended-tracker simulate OUTPUT [--scene NAME] [--seed N] [--duration S]
    extended-tracker real [--data DIR] [--out DIR] [--config YAML]
    extended-tracker evaluate OUTPUT_BAG --truth TRUTH [--plot PNG]
    extended-tracker results [--readme doc/results.md]
    extended-tracker bench [--quick] [--memory N] [--png PNG] [--profile]
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
import signal
import sys
import threading

import numpy as np

from . import __version__, stopping
from .errors import BagError, ConfigError, ExtendedTrackerError

# bags in ../shared/data/real with more than one LaserScan topic: the topics to replay
# (Freiburg's two are one scanner published twice; the replay would take the busier)
REAL_TOPICS = {
    'freiburg_corridor_stationary_sick': '/RAWLASER1',
}
# bags in ../shared/data/real with two scanners and no transforms between them: the
# mounts file (in --mounts-dir, config/mounts) that places them on the robot
REAL_MOUNTS = {
    'mir_legs_test_stationary': 'mir_100.yaml',
    'obstacle_detector_scans_demo': 'obstacle_detector_demo.yaml',
}


def load_config(path, preset_name=None):
    from .config import preset, TrackerConfig

    if path is not None and preset_name is not None:
        raise ConfigError('give --config or --preset, not both')
    if preset_name is not None:
        return preset(preset_name)
    if path is None:
        return TrackerConfig()
    from .configio import load_yaml

    return load_yaml(path)


def cmd_replay(args) -> int:
    from .bag.replay import replay
    from .bag.scanners import load_mounts, Mounts

    cfg = load_config(args.config, args.preset)
    mounts = load_mounts(args.mounts) if args.mounts else Mounts()
    summary = replay(args.input, args.output, cfg, args.scan_topic, args.plot,
                     progress=not args.quiet, fixed_frame=args.fixed_frame, mounts=mounts)
    for line in summary.lines():
        print(line)
    print(f'output bag       {summary.output}')
    if summary.plot:
        print(f'plot             {summary.plot}')
    return 0


SCENES = ('demo', 'tutorial', 'occlusion', 'mixed_traffic', 'walls', 'corridor_drive',
          'two_scanners', 'tutorial_legs', 'walls_legs', 'counting')


def cmd_simulate(args) -> int:
    from .sim.bag import write_sim_bag

    info = write_sim_bag(args.output, args.scene, args.seed, args.duration)
    print(json.dumps(info, indent=2))
    return 0


def _replay_output(bag: Path) -> bool:
    """Whether ``bag`` is a ROS 2 bag folder written by ``replay`` (it holds the tracks)."""
    from .bag.bagio import TRACKS_TYPE

    meta = bag / 'metadata.yaml'
    try:
        return meta.is_file() and TRACKS_TYPE in meta.read_text(errors='replace')
    except OSError:
        return False


def _print_real(label: str, s, config: str) -> None:
    """One bag's row of ``real``, with its events, renamed frames and fixed frame."""
    print(f'{label:48s} {s.scans:6d} {s.valid_detections / max(s.scans, 1):8.1f} '
          f'{s.distinct_ids:5d} {s.moving_ids:6d} {s.mean_count:6.2f} '
          f'{s.median_ms:7.2f} {s.p99_ms:7.2f}  {config}')
    for event, count in sorted(s.events.items()):
        why = s.first_reasons.get(event)
        print(f'  {event} {count}' + (f' (first: {why})' if why else ''))
    for old, new in sorted(s.renamed_frames.items()):
        print(f'  frame_id {old!r} written as {new!r}')
    if s.fixed_frame:
        print(f'  tracked in {s.fixed_frame} ({s.frame_why})')
    if s.legs_from is not None:
        print(f'  legs seen {s.legs_seen()}')


def cmd_real(args) -> int:
    from .bag.replay import replay
    from .bag.scanners import load_mounts, Mounts
    from .config import TrackerConfig

    data = Path(args.data)
    out = Path(args.out)
    if not data.exists():
        raise BagError(f'--data {data} does not exist')
    if (data / 'metadata.yaml').is_file() or (data.is_file() and data.suffix == '.bag'):
        bags = [data]                              # DATA is one recording itself
    elif data.is_dir():
        # ROS 2 bag folders, and ROS 1 bag files, directly under DATA; not the --out
        # folder when it lies there (a PNG folder, not a bag)
        bags = sorted(p for p in data.iterdir() if (p.is_dir() or p.suffix == '.bag')
                      and not (out.exists() and p.resolve() == out.resolve()))
    else:
        bags = []
    if not bags:
        print(f'no recordings at {data} (ROS 2 bag folders or ROS 1 .bag files); '
              'nothing to do', file=sys.stderr)
        return 0
    out.mkdir(parents=True, exist_ok=True)
    given = load_config(args.config) if args.config else None
    print(f'{"bag":48s} {"scans":>6s} {"det/scan":>8s} {"ids":>5s} {"moving":>6s} '
          f'{"mean n":>6s} {"ms med":>7s} {"ms p99":>7s}  config')
    failed = 0
    for bag in bags:
        label = bag.name if bag.is_dir() else bag.stem
        if bag != data and _replay_output(bag):
            # an earlier run's output (--out inside --data, or the same folder): replaying
            # it again would add a NAME_tracks_tracks on every run
            print(f'{label:48s} skipped: a replay output (it holds tracks), not a recording')
            continue
        target = out / f'{label}_tracks'
        if target.exists():
            import shutil

            shutil.rmtree(target)
        cfg = given or TrackerConfig()
        try:
            mounts = (load_mounts(Path(args.mounts_dir) / REAL_MOUNTS[label])
                      if label in REAL_MOUNTS else Mounts())
            s = replay(bag, target, cfg, REAL_TOPICS.get(label), out / f'{label}.png',
                       progress=False, mounts=mounts)
        except BagError as err:              # one unreadable bag does not stop the others
            failed += 1
            print(f'{label:48s} not replayed: {err}')
            continue
        _print_real(label, s, '--config' if given else 'defaults')
    print(f'bags and PNGs in {out}')
    if failed:
        print(f'{failed} of {len(bags)} not replayed', file=sys.stderr)
        return 1
    return 0


def cmd_evaluate(args) -> int:
    from .evaluation.evaluate import evaluate_bag, GOSPA_C, GOSPA_P

    plot = None
    if args.plot:
        from .report.imagefile import image_path

        plot = image_path(args.plot)            # the name written (a .png added)
    score, per, stamps = evaluate_bag(args.output_bag, args.truth, plot)
    print(f'GOSPA (alpha 2, c {GOSPA_C:g} m, p {GOSPA_P:g}, Gaussian-Wasserstein), '
          f'{score.scans} scans')
    print(f'mean GOSPA        {score.gospa_mean:.3f} m')
    print(f'  localisation    {score.localisation_mean:.3f}   missed {score.missed_mean:.3f}'
          f'   false {score.false_mean:.3f}  (mean per scan, before the 1/p power)')
    print(f'cardinality error {score.cardinality_error:.3f} per scan')
    print(f'id switches       {score.id_switches}')
    print(f'fragmentations    {score.fragmentations}')
    if score.hidden:
        print(f'hidden kept       {score.hidden_kept} of {score.hidden} object-scans no beam '
              'reached had an estimate')
    t = (stamps - stamps[0]) * 1e-9
    print('over time (per second): ' + '  '.join(
        f'{int(s)}s {np.mean([g.total for g, tt in zip(per, t) if int(tt) == s]):.2f}'
        for s in range(int(t[-1]) + 1)))
    if plot:
        print(f'plot              {plot}')
    return 0


def cmd_results(args) -> int:
    from .evaluation.evaluate import results_table, scenario_notes, write_readme_results

    if args.readme:
        from .evaluation.recorded import write_recorded_results

        write_readme_results(Path(args.readme))
        print(f'results written into {args.readme}')
        if write_recorded_results(Path(args.readme), Path(args.recordings)):
            print('and the recordings with truth (../shared/data/moving) too')
    else:
        print(scenario_notes())
        print()
        print(results_table())
    return 0


def cmd_bench(args) -> int:
    from .evaluation.bench import main as bench_main

    # the benchmark parses its own options (``bench --help`` lists them): one definition
    return bench_main(args.passed_on)


def _add_replay(sub) -> None:
    """The ``replay`` command's options."""
    from .config import PRESETS

    r = sub.add_parser('replay', help='track the LaserScans of a bag into a new MCAP bag')
    r.add_argument('input', help='ROS 2 bag folder (sqlite3 or MCAP) or ROS 1 .bag')
    r.add_argument('--output', '-o', required=True, help='new ROS 2 bag folder (MCAP)')
    r.add_argument('--scan-topic', action='append',
                   help='a LaserScan topic to track (again for several; default: every one, '
                        'one of those that share a frame)')
    r.add_argument('--mounts', metavar='FILE',
                   help='the scanners\' mounts on the robot for a bag without their '
                        'transforms (base_frame, mounts: {FRAME: [x, y, yaw]}; '
                        'config/mounts/ has examples)')
    r.add_argument('--fixed-frame', metavar='FRAME',
                   help='frame to track in, linked to the scan frame by the bag\'s /tf and '
                        '/tf_static ("" for the scan frame; default: tf.fixed_frame, odom, '
                        'where the bag links the scan frame to it, else the scan frame)')
    r.add_argument('--config', help='YAML config: plain sections, or a ROS 2 parameter file '
                                    '(the entries for the extended_tracker node)')
    r.add_argument('--preset', choices=sorted(PRESETS),
                   help='named changes from the defaults (leg_height: a scanner that sees '
                        'people only)')
    r.add_argument('--plot', help='write a picture of the run (PNG; .svg, .pdf, ... by '
                                 'the suffix)')
    r.add_argument('--quiet', action='store_true', help='no progress bar')
    r.set_defaults(func=cmd_replay)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog='extended-tracker',
        description='Extended object tracking in 2D laser scans: replay bags, simulate '
                    'scenes, evaluate against truth, measure speed.')
    p.add_argument('--version', action='version', version=f'%(prog)s {__version__}')
    sub = p.add_subparsers(dest='command', required=True)
    _add_replay(sub)
    s = sub.add_parser('simulate', help='write a simulated scan bag with ground truth')
    s.add_argument('output', help='new ROS 2 bag folder (MCAP), truth.json inside it')
    s.add_argument('--scene', choices=SCENES, default='demo',
                   help='scripted scene (default: %(default)s)')
    s.add_argument('--seed', type=int, default=0,
                   help='seed of the scan noise and clutter (default: %(default)s)')
    s.add_argument('--duration', type=float, default=12.0,
                   help='seconds of scans at 10 Hz, at most 3600 (default: %(default)s)')
    s.set_defaults(func=cmd_simulate)
    real = sub.add_parser('real', help='replay every bag of a folder of real recordings')
    real.add_argument('--data', default=os.path.join('..', 'shared', 'data', 'real'),
                      help='folder of ROS 2 bag folders and ROS 1 .bag files, or one bag '
                           '(default: %(default)s)')
    real.add_argument('--out', default=os.path.join('out', 'real'),
                      help='folder for the PNGs and the replayed bags (default: '
                           '%(default)s)')
    real.add_argument('--mounts-dir', default=os.path.join('config', 'mounts'),
                      help='folder of the mounts files of the two-scanner recordings '
                           '(default: %(default)s)')
    real.add_argument('--config', help='one config for every bag (default: the defaults)')
    real.set_defaults(func=cmd_real)
    e = sub.add_parser('evaluate', help='score a replayed bag against simulator truth')
    e.add_argument('output_bag', help='bag written by replay from a simulated bag')
    e.add_argument('--truth', required=True, help='truth.json written by simulate')
    e.add_argument('--plot', help='picture of GOSPA and cardinality against time (PNG; '
                                 '.svg, .pdf, ... by the suffix)')
    e.set_defaults(func=cmd_evaluate)
    res = sub.add_parser('results', help='run the scenario suite (CPHD/PHD x p_D models)')
    res.add_argument('--readme', help='write the table into this file between its markers')
    res.add_argument('--recordings', default='../shared/data/moving',
                     help='recordings with motion-capture truth to score too, where they are '
                          '(default: %(default)s)')
    res.set_defaults(func=cmd_results)
    # add_help=False: bench's options, --help included, go to the benchmark's own parser
    b = sub.add_parser('bench', add_help=False,
                       help='print per-scan timing figures (bench --help for its options)')
    b.set_defaults(func=cmd_bench)
    return p


def main(argv=None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra and args.func is not cmd_bench:
        parser.error(f'unrecognized arguments: {" ".join(extra)}')
    args.passed_on = extra
    # SIGTERM (a kill, a supervisor, a CI timeout) ends a command as Ctrl-C does: a replay
    # or simulate removes its staging folder instead of dying with it half written; the
    # handler of both records the signal, which outlives an exception lost in C code
    taken = None
    stopping.reset()
    if threading.current_thread() is threading.main_thread():
        taken = stopping.take(stopping.on_signal)
    try:
        if taken:
            stopping.unblock()          # one sent while a parent had them blocked: here
        status = args.func(args)
        # a signal whose exception C code swallowed (see stopping) still ends the command
        stopping.check()
        sys.stdout.flush()               # a closed pipe shows here, not at interpreter exit
        return status
    except BaseException as err:
        # a cleanup that fails while a stop unwinds (a writer closing half a record)
        # replaces it with its own exception: the signal recorded still says why the
        # command ended
        stop = stopping.received()
        if stop is not None:
            said = 'interrupted' if stop == signal.SIGINT else 'terminated'
            print(f'extended-tracker: {said}', file=sys.stderr)
            return 128 + stop                            # 130 for Ctrl-C, 143 for a kill
        if isinstance(err, BrokenPipeError):
            # the reader went away (`extended-tracker real | head`): end quietly, as a
            # process that SIGPIPE ends does; what stdout still holds goes nowhere
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            return 128 + signal.SIGPIPE
        if isinstance(err, (ExtendedTrackerError, OSError)):
            # OSError: a path that cannot be made or read, a full disk
            print(f'extended-tracker: error: {err}', file=sys.stderr)
            return 2
        if isinstance(err, KeyboardInterrupt):
            print('extended-tracker: interrupted', file=sys.stderr)
            return 130
        raise
    finally:
        stopping.give_back(taken)
        stopping.reset()                # the command's own: not seen by what runs next


if __name__ == '__main__':
    sys.exit(main())
