"""The run picture's sketch: every scan's tracks, a bounded and even sample of the clouds."""

import tracemalloc

import numpy as np
import pytest

from extended_tracker.config import TrackerConfig
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.report.plotting import plot_run, RunSketch
from extended_tracker.sim.laser import demo_scene, simulate

CFG = TrackerConfig()


@pytest.fixture(scope='module')
def results():
    """Thirty scans of the demo scene: walkers tracked, the walls learned as background."""
    state, out = PipelineState.initial(CFG), []
    for scan, _ in simulate(demo_scene(), 3.0, seed=0):
        state, res = step(state, scan, CFG)
        out.append(res)
    assert sum(len(r.estimates) for r in out) > 0
    assert sum(len(r.background_points) for r in out) > 0 < sum(len(r.points) for r in out)
    return out


def test_under_the_budget_the_sketch_keeps_every_scan_and_every_track_row(results):
    sketch = RunSketch(max_points=10**6)
    for r in results:
        sketch.add(r)
    assert sketch.scans == len(results) and sketch.stride == 1
    want_pts = [r.points for r in results if len(r.points)]
    want_bg = [r.background_points for r in results if len(r.background_points)]
    assert len(sketch.points()) == len(want_pts) and len(sketch.background()) == len(want_bg)
    for got, want in zip(sketch.points() + sketch.background(), want_pts + want_bg):
        np.testing.assert_array_equal(got, want)
    # the track rows are the estimates' centres and outline axes, scan by scan
    rows = {}
    for r in results:
        e = r.estimates
        major, minor, yaw = e.axes()
        for j, lab in enumerate(e.label.tolist()):
            rows.setdefault(lab, []).append([*e.m[j, :2], major[j], minor[j], yaw[j], 0.0])
    assert sorted(sketch.tracks) == sorted(rows)
    for lab, want in rows.items():
        np.testing.assert_array_equal(sketch.track(lab), np.array(want))


def test_the_cloud_sample_stays_in_budget_and_evenly_spread(results):
    """Over a long run the sample thins to every stride-th scan, the stride a power of two,
    while the tracks keep every scan."""
    budget = 2_000
    sketch = RunSketch(max_points=budget)
    n = 50 * len(results)                                    # 1,500 scans
    for k in range(n):
        sketch.add(results[k % len(results)])
    scans = [c[0] for c in sketch.clouds]
    s = sketch.stride
    assert s > 1 and s & (s - 1) == 0
    assert all(k % s == 0 for k in scans)
    # every stride-th scan with returns is there: the sample covers the whole run
    with_returns = [k for k in range(0, n, s) if len(results[k % len(results)].points)
                    or len(results[k % len(results)].background_points)]
    assert scans == with_returns and scans[-1] >= n - s - len(results)
    kept = sum(len(c[1]) + len(c[2]) + RunSketch.SCAN_COST for c in sketch.clouds)
    assert kept <= 2 * budget
    per_pass = sum(len(r.estimates) for r in results)
    assert sum(len(sketch.track(lab)) for lab in sketch.tracks) == 50 * per_pass


def test_a_long_run_holds_bounded_memory_for_the_clouds(results):
    """Memory of a sketch over 20,000 scans: the clouds stay within the budget; what grows
    is the tracks' six floats per object and scan."""
    budget = 20_000
    sketch = RunSketch(max_points=budget)
    objects = 0
    tracemalloc.start()
    try:
        for k in range(20_000):
            r = results[k % len(results)]
            sketch.add(r)
            objects += len(r.estimates)
        used = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    clouds = 2 * budget * 16 + 400 * len(sketch.clouds) + 100_000     # points, headers
    tracks = objects * 6 * 8 * 1.2 + 10_000                            # array growth slack
    assert used < clouds + tracks, (used, clouds, tracks)
    # without the sample every scan's returns would be kept: far above that bound
    every_scan = sum(16 * (len(r.points) + len(r.background_points)) for r in results) * 1000
    assert every_scan > 3 * (clouds + tracks)



def _made_up(n_points, labels=(), n_background=0):
    """A result with ``n_points`` detections, ``n_background`` background returns and
    estimates of ``labels``."""
    from types import SimpleNamespace

    from mixtures import estimates

    est = estimates(list(labels), np.array([[k, 1.0] for k in range(len(labels))]).reshape(-1, 2))
    return SimpleNamespace(estimates=est, points=np.zeros((n_points, 2)),
                           background_points=np.ones((n_background, 2)))


def test_the_sample_thins_once_its_cost_passes_twice_the_budget_and_not_before():
    """Each scan costs its returns and ``SCAN_COST`` more: with 76 returns a scan costs
    100, so a budget of 1,000 holds 20 scans (2,000) whole and thins at the 21st."""
    assert RunSketch.SCAN_COST == 24
    sketch = RunSketch(max_points=1_000)
    for _ in range(20):
        sketch.add(_made_up(76))
    assert sketch.stride == 1 and len(sketch.clouds) == 20
    sketch.add(_made_up(76))
    assert sketch.stride == 2 and [c[0] for c in sketch.clouds] == list(range(0, 21, 2))


def test_the_sketch_draws_as_boxes_what_its_is_rectangle_says():
    sketch = RunSketch(is_rectangle=lambda e: e.label % 2 == 0)
    sketch.add(_made_up(5, labels=(3, 4, 6)))
    assert [sketch.track(lab)[0, 5] for lab in (3, 4, 6)] == [0.0, 1.0, 1.0]
    assert RunSketch().tracks == {}


def test_the_view_holds_the_scene_with_a_metre_to_spare_and_the_sensor():
    """
    Returns in a 2 m square behind and left of the scanner (x -4..-2, y 2..4) and three
    far strays: the view reaches a metre beyond the square (the 0.5 and 99.5 percentiles
    leave the strays out) and holds the scanner, half a metre inside on every side.
    """
    from extended_tracker.report.plotting import plot_limits

    g = np.linspace(0.0, 2.0, 40)
    square = np.column_stack([np.repeat(g, 40) - 4.0, np.tile(g, 40) + 2.0])
    strays = np.array([[-100.0, 100.0], [-90.0, 95.0], [-95.0, 90.0]])
    lo, hi = plot_limits([square, strays])
    assert -5.0 <= lo[0] <= -4.95 and 4.95 <= hi[1] <= 5.0
    assert (lo[1], hi[0]) == (-0.5, 0.5)
    assert plot_limits([np.zeros((0, 2))]) is None


def test_a_scene_far_wider_than_deep_gets_the_widest_picture_and_a_readable_height():
    from extended_tracker.report.plotting import figure_size

    assert figure_size((np.array([0.0, -0.5]), np.array([100.0, 0.5]))) == (16.0, 4.0)
    assert figure_size((np.array([-0.5, 0.0]), np.array([0.5, 100.0]))) == (4.0, 10.0)
    assert figure_size(None) == (10.0, 8.0)


def test_what_plot_run_draws(tmp_path, saved_figures):
    """
    Twelve scans of 500 returns and 300 background ones each, gathered whole; label 1
    in all of them, label 4 too (a box, as ``is_rectangle`` says), label 2 in three
    only; ids in fewer than 12 scans are short. Drawn: the field of view as a wedge
    (degrees), 1,000 of the returns (every sixth) and 1,200 of the background's (every
    third), each long id's trajectory in its RViz marker colour with outlines (the box as
    a rectangle: four corners), the short id as a grey trace without outlines, counted in
    the title.
    """
    import math

    import matplotlib.colors
    from matplotlib.patches import Polygon, Wedge

    from extended_tracker.report.messages import id_rgba, outline_xy

    run = []
    for k in range(12):
        r = _made_up(500, labels=(1, 2, 4) if k < 3 else (1, 4), n_background=300)
        r.estimates.X[:] = np.diag([0.09, 0.04])
        r.estimates.m[:, 0] += 0.1 * k
        run.append(r)
    sketch = RunSketch(is_rectangle=lambda e: e.label == 4)       # keeps all 6,000
    for r in run:
        sketch.add(r)
    plot_run(sketch, tmp_path / 'p.png', fov=(-math.pi / 2, math.pi / 2, 10.0),
             max_points=1_000, min_scans=12)
    (fig,) = saved_figures
    ax = fig.axes[0]
    (wedge,) = [p for p in ax.patches if isinstance(p, Wedge)]
    assert (wedge.theta1, wedge.theta2, wedge.r) == pytest.approx((-90.0, 90.0, 10.0))
    background, cloud = ax.collections
    assert len(cloud.get_offsets()) == 1_000
    assert len(background.get_offsets()) == 1_200              # of 3,600: every third
    colours = [matplotlib.colors.to_rgb(line.get_color()) for line in ax.get_lines()]
    for lab in (1, 4):
        c = id_rgba(lab)
        assert colours.count(pytest.approx((c['r'], c['g'], c['b']))) == 1, lab
    assert colours.count(pytest.approx(matplotlib.colors.to_rgb('0.55'))) == 1
    outlines = [p.get_xy() for p in ax.patches if isinstance(p, Polygon)]
    box = outline_xy(np.array([2.1, 1.0]), 0.3, 0.2, 0.0, True)          # label 4, last
    ellipse = outline_xy(np.array([1.1, 1.0]), 0.3, 0.2, 0.0, False)    # label 1, last
    assert any(len(xy) == len(box) == 5 and np.allclose(xy, box) for xy in outlines)
    assert any(np.allclose(xy[:len(ellipse)], ellipse) for xy in outlines)
    # label 2's (centre (1.2, 1.0) in its last scan): none
    assert not any(np.allclose(xy[:-1].mean(axis=0), [1.2, 1.0]) for xy in outlines)
    assert '(grey: 1 ids reported in fewer than 12 scans)' in ax.get_title()

def test_plot_run_draws_a_list_or_a_sketch_alike(results, tmp_path):
    sketch = RunSketch()
    for r in results:
        sketch.add(r)
    plot_run(results, tmp_path / 'list.png', title='t')
    plot_run(sketch, tmp_path / 'sketch.png', title='t')
    a, b = (tmp_path / 'list.png').read_bytes(), (tmp_path / 'sketch.png').read_bytes()
    assert len(a) > 10_000 and a == b


def _png_size(path):
    """Width and height (pixels) from a PNG's header."""
    head = path.read_bytes()[16:24]
    return int.from_bytes(head[:4], 'big'), int.from_bytes(head[4:], 'big')


def test_the_picture_takes_the_proportions_of_a_long_scene(results, tmp_path, saved_figures):
    """
    A scene about as wide as deep (the demo room) keeps the 10 x 8 inch picture; a
    corridor 21 m long and 3 m wide (the Freiburg recording's kind) gets a wide one, whose
    axes, drawn at equal scale, fill a larger share of it than the 10 x 8 inches did
    (there, a strip under two inches high).
    """
    from types import SimpleNamespace

    import matplotlib.pyplot as plt

    from extended_tracker.tracks.estimates import Estimates

    plot_run(results, tmp_path / 'room.png', title='t')
    assert _png_size(tmp_path / 'room.png') == (1100, 880)
    rng = np.random.default_rng(0)
    corridor = SimpleNamespace(
        estimates=Estimates.empty(),
        points=np.column_stack([rng.uniform(0, 20, 500), rng.uniform(-1.5, 1.5, 500)]),
        background_points=np.zeros((0, 2)))
    plot_run([corridor], tmp_path / 'corridor.png', title='t')
    box = saved_figures[-1].axes[0].get_position()      # the share the axes take, drawn
    share = box.width * box.height
    w, h = _png_size(tmp_path / 'corridor.png')
    assert w >= 3 * h
    fig, ax = plt.subplots(figsize=(10, 8))            # the corridor in the 10 x 8 inches
    ax.set_aspect('equal')
    ax.set_xlim(-1, 21)
    ax.set_ylim(-2.5, 2.5)
    fig.tight_layout()
    fig.canvas.draw()
    box = ax.get_position()
    plt.close(fig)
    assert share > 2 * box.width * box.height


def test_the_image_suffixes_are_those_savefig_writes_less_pgf():
    """imagefile keeps matplotlib out of the name check (the bench checks first, then
    times); its list must be the pinned matplotlib's, pgf left out (it needs LaTeX)."""
    import subprocess
    import sys

    from matplotlib.backend_bases import FigureCanvasBase

    from extended_tracker.report.imagefile import IMAGE_SUFFIXES

    assert set(IMAGE_SUFFIXES) == set(FigureCanvasBase.get_supported_filetypes()) - {'pgf'}
    loaded = subprocess.run([sys.executable, '-c', 'import sys, extended_tracker.report.imagefile; '
                             'print("matplotlib" in sys.modules)'], capture_output=True,
                            text=True, check=True)
    assert loaded.stdout.strip() == 'False'
