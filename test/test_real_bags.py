"""The real recordings give the figures of test/data/real_bags.json (slow: full replays)."""

import json
from pathlib import Path

import pytest

from extended_tracker.bag.bagio import open_scans
from extended_tracker.bag.replay import replay, ros2_frame_id
from extended_tracker.bag.scanners import load_mounts, Mounts
from extended_tracker.cli import load_config, REAL_MOUNTS, REAL_TOPICS
from extended_tracker.pipeline import PipelineState, step

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / 'shared' / 'data' / 'real'
GOLDEN = json.loads((Path(__file__).parent / 'data' / 'real_bags.json').read_text())
TOL = GOLDEN['tolerance']

pytestmark = [pytest.mark.slow,
              pytest.mark.skipif(not REAL.is_dir(), reason=f'no real recordings at {REAL}')]


@pytest.mark.parametrize('name', sorted(GOLDEN['recordings']))
def test_a_real_recording_gives_its_figures(name, tmp_path):
    """Scans, detections per scan, ids, moving ids and mean count of one recording, as
    `extended-tracker real` replays it (the defaults, its topic and mounts)."""
    want = GOLDEN['recordings'][name]
    assert want['config'] == 'defaults'
    mounts = (load_mounts(ROOT / 'config' / 'mounts' / REAL_MOUNTS[name])
              if name in REAL_MOUNTS else Mounts())
    s = replay(REAL / name, tmp_path / name, load_config(None), REAL_TOPICS.get(name),
               progress=False, mounts=mounts)
    assert (s.scans, s.distinct_ids, s.moving_ids) == (want['scans'], want['ids'],
                                                        want['moving'])
    assert s.valid_detections / s.scans == pytest.approx(want['detections_per_scan'],
                                                         abs=TOL['detections_per_scan'])
    assert s.mean_count == pytest.approx(want['mean_count'], abs=TOL['mean_count'])
    assert s.fixed_frame == want['fixed_frame']


def test_every_recording_has_its_figures():
    folders = sorted(p.name for p in REAL.iterdir() if p.is_dir())
    assert folders == sorted(GOLDEN['recordings'])


def thinned_run(name, topic, every, preset=None):
    """Distinct ids and mean reported count of a recording replayed with only every
    ``every``-th of its scans (the scan rate divided by ``every``)."""
    cfg = load_config(None, preset)
    reader, conns = open_scans(REAL / name, topic)
    state, ids, counts = PipelineState.initial(cfg), set(), []
    try:
        for k, (conn, record_ns, raw) in enumerate(reader.messages(connections=conns)):
            if k % every:
                continue
            scan = reader.deserialize(raw, conn.msgtype)
            scan.header.frame_id = ros2_frame_id(scan.header.frame_id)
            state, res = step(state, scan, cfg, arrival_ns=record_ns)
            ids.update(res.estimates.label.tolist())
            counts.append(len(res.estimates))
    finally:
        reader.close()
    return len(ids), sum(counts) / len(counts)


@pytest.mark.parametrize('case', GOLDEN['freiburg_thinned'],
                         ids=lambda c: f'{c["topic"]}-every{c["every"]}-{c["preset"]}')
def test_the_freiburg_recording_at_lower_scan_rates(case):
    """Freiburg's 45 Hz /RAWLASER1 thinned to 22 and 11 Hz, and the 9 Hz /ROBOTLASER1,
    on the defaults."""
    ids, mean = thinned_run('freiburg_corridor_stationary_sick', case['topic'],
                            case['every'], case['preset'])
    assert ids == case['ids']
    assert mean == pytest.approx(case['mean_count'], abs=TOL['mean_count'])
