"""Evaluation: a simulated bag replayed and scored against its truth, from the command line."""

from pathlib import Path
import subprocess
import sys

from extended_tracker.evaluate import evaluate_bag, run_scenario, VARIANTS
from extended_tracker.replay import replay
from extended_tracker.config import from_dict
from extended_tracker.sim.bag import write_sim_bag


def test_replayed_bag_scores_against_its_truth(tmp_path):
    write_sim_bag(tmp_path / 'scans', 'occlusion', seed=0, duration=6.0)
    cfg = from_dict({'background': {'enabled': False}})
    replay(tmp_path / 'scans', tmp_path / 'out', cfg, progress=False)
    score, per, stamps = evaluate_bag(tmp_path / 'out', tmp_path / 'scans' / 'truth.json',
                                      plot=tmp_path / 'g.png')
    assert score.scans == 60 == len(per) == len(stamps)
    # two pedestrians, one hidden behind the other for ~2 s: kept, so GOSPA stays small
    # (a missed pedestrian alone costs sqrt(2) = 1.41 m in a scan)
    assert score.gospa_mean < 0.8 and score.id_switches == 0
    assert (tmp_path / 'g.png').stat().st_size > 10_000
    exe = Path(sys.executable).with_name('extended-tracker')
    done = subprocess.run([str(exe), 'evaluate', str(tmp_path / 'out'), '--truth',
                           str(tmp_path / 'scans' / 'truth.json')], capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert 'mean GOSPA' in done.stdout and 'id switches       0' in done.stdout


def test_scan_shadow_beats_constant_pd_on_the_tutorial_scenario():
    shadow, _ = run_scenario('tutorial', VARIANTS['CPHD, scan shadow'])
    constant, _ = run_scenario('tutorial', VARIANTS['CPHD, constant p_D'])
    assert shadow.gospa_mean < constant.gospa_mean
    assert shadow.id_switches < constant.id_switches
