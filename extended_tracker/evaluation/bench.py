"""
Timing and memory figures (printed, never asserted): ``extended-tracker bench``.

- filter: one full filter step (partition, predict, update, reduce, extract) on the
  returns of simulated scans of N pedestrians, against N (1-50) and, in finer scans, the
  detections (to about 1000); N = 0 (no returns, no tracks) is the fixed cost of the
  chain that every scan pays. The growth of the time above that fixed cost is fitted as
  a power of objects x cells and of the detections (1 is linear);
- pipeline: ``pipeline.step`` on the scenario scans S1 (tutorial-like, 361 beams, four
  pedestrians), S2 (1081 beams / 270 deg, a car, two bicycles, seven pedestrians, 3
  clutter returns) and S3 (1081 beams, 40 objects, 20 clutter returns), with the caps
  that bit;
- targets: the issues' target cases (4 pedestrians, 10 objects at 1081 beams, S1-S3) in
  interleaved rounds (``--rounds R``), since this machine's speed drifts by tens of
  percent from minute to minute: pooled median and p99, the spread of the rounds'
  medians, and how many rounds met the targets;
- memory: resident memory over many scans (``--memory N``);
- profile: where the time of the 4-pedestrian filter step goes (``--profile``);
- machine: the CPU, the numpy build's SIMD level, the cost of float64 ``exp`` per
  element (scalar or vectorised), and a yardstick of the machine's speed in the minute
  the figures were taken (a fixed workload of small numpy calls, the kind the filter step
  is made of), timed at the start, in every target round and at the end.
"""

from __future__ import annotations

import argparse
from pathlib import Path
import time

import numpy as np

from ..config import from_dict
from ..pipeline import PipelineState, step
from ..sensing.scan import scan_to_points
from ..sim.laser import crowd_scene, mixed_traffic_scene, Scene, simulate, tutorial_scene
from ..tracker import filter_step, TrackerState
from .timing import (
    _growth_cases, exp_ns, growth_exponent, machine_line, peak_rss_mb, reference_ms, report_growth,
    rss_mb, timing_stats,
)


def stress_scene() -> Scene:
    """S3: 40 pedestrians, 1081 beams over 270 deg, 30 m, 20 clutter returns per scan."""
    return crowd_scene(40, seed=11, beams=1081, fov_deg=270.0, range_max=30.0, clutter=20.0)


def bench_filter(counts, scans, warm=10, run_scans=60, beams=361, fov_deg=180.0):
    """
    Median and p99 of one filter step on the returns of N pedestrians.

    Each case repeats short runs of ``run_scans`` scans over several seeds, so that the
    walkers are still in view (over a long run they walk out of the field of view).
    Returns ``(objects, detections, cells, median ms)`` per case.
    """
    print(f'filter step (partition, predict, update, reduce, extract), {beams} beams over '
          f'{fov_deg:g} deg, p_D const')
    print(f'{"objects":>8s} {"detections":>10s} {"cells":>6s} {"partitions":>10s} '
          f'{"median ms":>9s} {"p99 ms":>7s}')
    rows = []
    for n in counts:
        dets, cells, parts, med, p99 = _filter_case(n, beams, fov_deg, scans, warm, run_scans)
        rows.append((n, dets, cells, med))
        print(f'{n:8d} {dets:10.0f} {cells:6.0f} {parts:10.1f} {med:9.2f} {p99:7.2f}')
    return rows


def _filter_case(n, beams, fov_deg, scans, warm=10, run_scans=60):
    """Mean detections, cells and partitions, and the median and p99 ms of the filter
    step on ``n`` pedestrians in a scan of ``beams`` beams over ``fov_deg``."""
    cfg = from_dict({'background': {'enabled': False}})
    runs = _pedestrian_runs(n, max(1, scans // run_scans), run_scans, warm, beams, fov_deg)
    times, diags = _filter_times(runs, cfg, warm)
    med, p99, _ = timing_stats(times)
    return (float(np.mean([d.detections for d in diags])),
            float(np.mean([d.cells for d in diags])),
            float(np.mean([d.partitions for d in diags])), med, p99)


# the detections sweep: 10 and 50 pedestrians in ever finer 180 deg scans, to ~1000 returns
DETECTION_CASES = ((10, 1081), (10, 2000), (10, 3400), (50, 721), (50, 1450))


def bench_detections(scans, cases=DETECTION_CASES, warm=10, run_scans=60):
    """
    The filter step against the detections: pedestrians in finer scans (more beams on
    each of them). Returns ``(objects, detections, cells, median ms)`` per case.
    """
    print('filter step against the detections (finer scans over 180 deg), p_D const')
    print(f'{"objects":>8s} {"beams":>6s} {"detections":>10s} {"cells":>6s} '
          f'{"partitions":>10s} {"median ms":>9s} {"p99 ms":>7s}')
    rows = []
    for n, beams in cases:
        dets, cells, parts, med, p99 = _filter_case(n, beams, 180.0, scans, warm, run_scans)
        rows.append((n, dets, cells, med))
        print(f'{n:8d} {beams:6d} {dets:10.0f} {cells:6.0f} {parts:10.1f} {med:9.2f} '
              f'{p99:7.2f}')
    return rows


def _filter_times(runs, cfg, warm):
    """Seconds of each filter step after the first ``warm`` of every run, and their
    diagnostics."""
    times, diags = [], []
    for pts in runs:
        state = TrackerState.initial(cfg)
        for k, sp in enumerate(pts):
            t0 = time.perf_counter()
            state, _, diag = filter_step(state, sp.points, 0.1, cfg, clutter_area=sp.area)
            dt = time.perf_counter() - t0
            if k >= warm:
                times.append(dt)
                diags.append(diag)
    return times, diags


def _pedestrian_runs(n, runs, run_scans, warm=10, beams=361, fov_deg=180.0):
    """The returns (and clutter areas) of ``runs`` simulated runs of ``n`` pedestrians."""
    out = []
    for rep in range(runs):
        seed = 1000 * n + rep
        data = simulate(crowd_scene(n, seed=seed, beams=beams, fov_deg=fov_deg),
                        (run_scans + warm) / 10.0, seed=seed)
        out.append([scan_to_points(scan) for scan, _ in data])
    return out


def bench_profile(n=4, runs=5, run_scans=60, top=25):
    """
    cProfile of the filter step on ``n`` pedestrians: the functions by cumulative time.

    Profiling adds a fixed cost per Python call (the step runs about 1.4 times slower),
    so read the shares, not the milliseconds.
    """
    import cProfile
    import pstats

    cfg = from_dict({'background': {'enabled': False}})
    runs_pts = _pedestrian_runs(n, runs, run_scans)
    _filter_times(runs_pts, cfg, 0)                   # warm the caches first
    prof = cProfile.Profile()
    prof.enable()
    _filter_times(runs_pts, cfg, 0)
    prof.disable()
    steps = sum(len(p) for p in runs_pts)
    print(f'\nprofile of the filter step, {n} pedestrians, {steps} steps '
          f'(cumulative time per function; under the profiler)')
    pstats.Stats(prof).sort_stats('cumulative').print_stats(r'extended_tracker', top)


def _pipeline_cases(scans):
    """The scenario cases S1-S3: name, configuration and ``scans`` scans (+ 2 s of warm-up)."""
    cases = [
        ('S1 tutorial-like, 4 pedestrians', tutorial_scene(), {'background': {'enabled': False}}),
        ('S2 car, 2 bicycles, 7 pedestrians', mixed_traffic_scene(),
         {'model': {'clutter_rate': 3.0}}),
        ('S3 stress, 40 objects, 20 clutter', stress_scene(),
         {'model': {'clutter_rate': 20.0, 'n_max': 60}}),
    ]
    return [(name, scene, from_dict(cfgd), simulate(scene, scans / 10.0 + 2.0, seed=1))
            for name, scene, cfgd in cases]


def _pipeline_times(data, cfg, warm=20):
    """``pipeline.step`` seconds of each scan after the first ``warm``, and the results."""
    state = PipelineState.initial(cfg)
    times, results = [], []
    for k, (scan, _) in enumerate(data):
        state, res = step(state, scan, cfg)
        if k >= warm:
            times.append(res.processing_time)
            results.append(res)
    return times, results


def bench_pipeline(scans):
    print('\nper-scan pipeline.step (convert, background, p_D, filter, extract)')
    print(f'{"scenario":40s} {"beams":>5s} {"det":>5s} {"median ms":>9s} {"p99 ms":>7s} '
          f'{"max ms":>7s} {"caps hit (partitions/cells/components)":>40s}')
    for name, scene, cfg, data in _pipeline_cases(scans):
        times, results = _pipeline_times(data, cfg)
        dets = [r.diagnostics['detections'] - r.diagnostics['background_dropped']
                for r in results]
        caps = np.zeros(3, int)
        for r in results:
            d = r.diagnostics
            caps += [d['capped_partitions'] > 0, d['capped_cells'] > 0,
                     d['capped_components'] > 0]
        med, p99, mx = timing_stats(times)
        print(f'{name:40s} {scene.laser.n_beams:5d} {np.mean(dets):5.0f} {med:9.2f} '
              f'{p99:7.2f} {mx:7.2f} {"/".join(str(c) for c in caps):>40s}')


def bench_targets(rounds=5, scans=300, run_scans=60, warm=10):
    """
    The issues' speed targets, each case timed in ``rounds`` interleaved rounds.

    This machine's speed drifts by tens of percent from one minute to the next, so a
    single pass per case measures the minute as much as the code. Every round times
    every case once (in alternating order); the figures are the median and p99 of all
    rounds' steps together, the spread of the rounds' medians, and in how many rounds
    the case met its targets.
    """
    cfg = from_dict({'background': {'enabled': False}})
    n_runs = max(1, scans // run_scans)
    peds4 = _pedestrian_runs(4, n_runs, run_scans, warm)
    # the detection counts as well: 4 pedestrians at 481 beams give some 60
    # returns (46 at 361), 10 at 1441 beams over 270 degrees some 250 (194 at 1081)
    peds4_60 = _pedestrian_runs(4, n_runs, run_scans, warm, beams=481)
    wide10 = _pedestrian_runs(10, n_runs, run_scans, warm, beams=1081, fov_deg=270.0)
    wide10_250 = _pedestrian_runs(10, n_runs, run_scans, warm, beams=1441, fov_deg=270.0)
    cases = [('filter step, 4 pedestrians, 361 beams',
              lambda: _filter_times(peds4, cfg, warm)[0], 1.5, None),
             ('filter step, 4 pedestrians, 481 beams',
              lambda: _filter_times(peds4_60, cfg, warm)[0], 1.5, None),
             ('filter step, 10 pedestrians, 1081 beams',
              lambda: _filter_times(wide10, cfg, warm)[0], 5.0, None),
             ('filter step, 10 pedestrians, 1441 beams',
              lambda: _filter_times(wide10_250, cfg, warm)[0], 5.0, None)]
    for (name, _, c, data), (med_t, p99_t) in zip(_pipeline_cases(scans),
                                                  [(2.0, 6.0), (6.0, 20.0), (None, 25.0)]):
        cases.append((name, lambda data=data, c=c: _pipeline_times(data, c)[0], med_t, p99_t))
    pooled = {name: [] for name, *_ in cases}
    medians = {name: [] for name, *_ in cases}
    met = dict.fromkeys(pooled, 0)
    yardstick = []
    for r in range(rounds):
        yardstick.append(reference_ms())
        for name, run, med_t, p99_t in (cases if r % 2 == 0 else cases[::-1]):
            t = run()
            pooled[name] += t
            med, p99, _ = timing_stats(t)
            medians[name].append(med)
            met[name] += (med_t is None or med <= med_t) and (p99_t is None or p99 <= p99_t)
    print(f'\ntargets, {rounds} interleaved rounds (median and p99 over all rounds; '
          f'the rounds\' medians; rounds within target)')
    print(f'{"case":40s} {"median ms":>9s} {"p99 ms":>7s} {"round medians ms":>17s} '
          f'{"target ms":>15s} {"rounds met":>10s}')
    for name, _, med_t, p99_t in cases:
        med, p99, _ = timing_stats(pooled[name])
        lo, hi = min(medians[name]), max(medians[name])
        target = ' / '.join('-' if t is None else f'{t:g}' for t in (med_t, p99_t))
        print(f'{name:40s} {med:9.2f} {p99:7.2f} {f"{lo:.2f}-{hi:.2f}":>17s} {target:>15s} '
              f'{f"{met[name]}/{rounds}":>10s}')
    print('reference workload at the start of each round (ms): '
          + ', '.join(f'{t:.2f}' for t in yardstick))
    # a round over target next to its yardstick tells a slow minute from slow code
    print('each round: its yardstick | every case\'s median, in the table\'s order (ms)')
    for r, ref in enumerate(yardstick):
        print(f'  round {r + 1}  {ref:.2f} | '
              + ' '.join(f'{medians[name][r]:.2f}' for name, *_ in cases))
    return pooled


def bench_memory(n_scans):
    """Resident memory growth over ``n_scans`` scans of S1, looping the same 60 s."""
    cfg = from_dict({'background': {'enabled': False}})
    data = [s for s, _ in simulate(tutorial_scene(), 60.0, seed=4)]
    state = PipelineState.initial(cfg)
    step_ns = 100_000_000
    base_ns = data[0].header.stamp.sec * 10**9 + data[0].header.stamp.nanosec
    rss = []
    import copy

    for k in range(n_scans):
        scan = copy.copy(data[k % len(data)])
        ns = base_ns + k * step_ns
        scan.header = copy.copy(scan.header)
        scan.header.stamp = type(scan.header.stamp)(ns // 10**9, ns % 10**9)
        state, _ = step(state, scan, cfg)
        if k % 1000 == 0 or k == n_scans - 1:
            rss.append((k, rss_mb()))
    print(f'\nresident memory over {n_scans} scans: ' + ', '.join(f'{k}: {m:.1f} MB'
                                                              for k, m in rss))
    # growth after the first 1000 scans (caches filled), when the run is longer than that
    k0, m0 = rss[1] if len(rss) > 2 else rss[0]
    print(f'growth from scan {k0} to {rss[-1][0]}: {rss[-1][1] - m0:.2f} MB')
    print(f'peak resident memory of the bench process (all cases so far): '
          f'{peak_rss_mb():.1f} MB')


def bench_scaling(png: str, scans: int = 40, growth_rows=None, fixed_ms: float = 0.0):
    """
    Time against objects (1-50, 361 beams) and against beams (361-4000, 10 objects); with
    ``growth_rows`` (``(objects, detections, cells, median ms)`` of filter steps) a third
    panel: their time above ``fixed_ms`` against objects x cells, log-log, with the fitted
    power and a linear slope for reference.
    """
    cfg = from_dict({'background': {'enabled': False}})
    rows_o, rows_b = [], []
    for n in (1, 2, 5, 10, 20, 30, 40, 50):
        rows_o.append((n, _median_step(crowd_scene(n, seed=n), cfg, scans)))
    for beams in (361, 721, 1081, 2000, 3000, 4000):
        rows_b.append((beams, _median_step(crowd_scene(10, seed=3, beams=beams), cfg, scans)))
    print('\nscaling (median ms per scan): objects ' +
          ', '.join(f'{n}: {t:.1f}' for n, t in rows_o) + ' | beams (10 objects) ' +
          ', '.join(f'{b}: {t:.1f}' for b, t in rows_b))
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    cases = _growth_cases(growth_rows or [], fixed_ms)
    fig, axes = plt.subplots(1, 2 if cases is None else 3,
                             figsize=(10 if cases is None else 15, 4), dpi=110)
    a1, a2 = axes[0], axes[1]
    a1.plot(*zip(*rows_o), 'o-')
    a1.set_xlabel('objects (361 beams)')
    a1.set_ylabel('median ms per scan (pipeline.step)')
    a2.plot(*zip(*rows_b), 'o-')
    a2.set_xlabel('beams (10 objects)')
    if cases is not None:
        x, _, y = cases
        k = growth_exponent(x, y)
        xs = np.geomspace(x.min(), x.max(), 50)
        # the fit's line and a linear slope, both through the cases' geometric mean
        gx, gy = np.exp(np.log(x).mean()), np.exp(np.log(y).mean())
        a3 = axes[2]
        a3.loglog(x, y, 'o', label='filter step cases')
        a3.loglog(xs, gy * (xs / gx) ** k, '-', label=f'fit: (objects x cells)^{k:.2f}')
        a3.loglog(xs, gy * (xs / gx), ':', label='linear')
        a3.set_xlabel('objects x cells')
        a3.set_ylabel(f'median ms above the fixed cost ({fixed_ms:.2f} ms)')
        a3.legend(fontsize=8)
    for a in axes:
        a.grid(alpha=0.3)
    fig.tight_layout()
    Path(png).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png)
    plt.close(fig)
    print(f'scaling curves: {png}')


def _median_step(scene, cfg, scans):
    state = PipelineState.initial(cfg)
    times = []
    for k, (scan, _) in enumerate(simulate(scene, (scans + 10) / 10.0, seed=1)):
        state, res = step(state, scan, cfg)
        if k >= 10:
            times.append(res.processing_time)
    return float(np.median(times) * 1e3)


def bench_node():
    try:
        from ..ros.bench_node import node_overhead
    except ImportError as err:         # no ROS in this environment
        print(f'\nnode overhead: skipped ({err})')
        return
    print()
    for listener, what in ((True, 'markers subscribed, as with RViz'),
                           (False, 'no marker subscriber: markers not built')):
        r = node_overhead(marker_listener=listener)
        print(f"node callback (step + messages + publish), {what}: median "
              f"{r['callback_median_ms']:.2f} ms, p99 {r['callback_p99_ms']:.2f} ms; step alone "
              f"{r['step_median_ms']:.2f} ms; overhead {r['overhead_median_ms']:.2f} ms")


def _count(text: str) -> int:
    """A whole number, 0 or more (argparse type: refused before any case runs)."""
    try:
        n = int(text)
    except ValueError:
        n = -1
    if n < 0:
        raise argparse.ArgumentTypeError(f'a whole number, 0 or more, is needed: {text!r}')
    return n


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog='extended-tracker bench')
    p.add_argument('--quick', action='store_true', help='fewer scans per case')
    p.add_argument('--memory', type=_count, default=0, metavar='N',
                   help='also run N scans for memory (growth from scan 1000 on when N > 1000)')
    p.add_argument('--png', default='out/bench/scaling.png', help='scaling curves PNG')
    p.add_argument('--profile', action='store_true',
                   help='only profile the 4-pedestrian filter step (cProfile, by function)')
    p.add_argument('--rounds', type=_count, default=5,
                   help='interleaved rounds of the target cases (0: skip them)')
    args = p.parse_args(argv)
    if args.profile:
        bench_profile()
        return 0
    from ..report.imagefile import image_path

    png = image_path(args.png)       # checked now, not after minutes of timing
    scans = 60 if args.quick else 300
    print(machine_line())
    print(f'float64 exp: {exp_ns():.1f} ns per element')
    print(f'reference workload (1000 small numpy operations): {reference_ms():.2f} ms at the '
          'start\n')
    rows = bench_filter([0, 1, 2, 4, 10, 20, 50], scans)
    print()
    # the second target case: 10 objects with ~250 returns (a finer, wider scan)
    rows += bench_filter([10], scans, beams=1081, fov_deg=270.0)
    print()
    rows += bench_detections(scans)
    report_growth(rows, rows[0][3])
    bench_pipeline(scans)
    if args.rounds > 0:
        bench_targets(args.rounds, scans)
    bench_node()
    bench_scaling(png, 20 if args.quick else 60, rows, rows[0][3])
    if args.memory:
        bench_memory(args.memory)
    print(f'\nreference workload: {reference_ms():.2f} ms at the end')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
