"""The README's table of the real recordings is what `make real` gives."""

from pathlib import Path
import re

import pytest

from extended_tracker.bagio import open_scans
from extended_tracker.cli import _config, REAL_PRESETS, REAL_TOPICS
from extended_tracker.pipeline import PipelineState, step
from extended_tracker.replay import replay, ros2_frame_id

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / 'shared' / 'data' / 'real'


def readme_rows():
    """``{recording: (scans, detections per scan, ids, moving, mean n, config)}``."""
    text = (ROOT / 'README.md').read_text().split('## Real data')[1]
    rows = {}
    for m in re.finditer(r'^\| `(\w+)` \| (\d+) \| ([\d.]+) \| (\d+) \| (\d+) \| ([\d.]+) '
                         r'\| [\d.]+ / [\d.]+ \| (.+) \|$', text, re.M):
        name, scans, det, ids, moving, mean, config = m.groups()
        rows[name] = (int(scans), det, int(ids), int(moving), mean, config.strip('`'))
    return rows


@pytest.mark.skipif(not REAL.is_dir(), reason=f'no real recordings at {REAL}')
def test_the_readme_real_data_table_is_what_make_real_gives(tmp_path):
    """Each recording's scans, detections per scan, ids, moving ids and mean count as the
    README's table gives them (`make real`'s figures; the times are the machine's)."""
    rows = readme_rows()
    folders = sorted(p.name for p in REAL.iterdir() if p.is_dir())
    assert sorted(rows) == folders
    for name in folders:
        preset = REAL_PRESETS.get(name)
        s = replay(REAL / name, tmp_path / name, _config(None, preset), REAL_TOPICS.get(name),
                   progress=False)
        got = (s.scans, f'{s.valid_detections / s.scans:.1f}', s.distinct_ids, s.moving_ids,
               f'{s.mean_count:.2f}', preset or 'defaults')
        assert got == rows[name], (name, 'run `make real` and update the README table')


def thinned_run(name, topic, every, preset=None):
    """Distinct ids and mean reported count of a recording replayed with only every
    ``every``-th of its scans (the scan rate divided by ``every``)."""
    cfg = _config(None, preset)
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
    return len(ids), f'{sum(counts) / len(counts):.2f}'


@pytest.mark.skipif(not REAL.is_dir(), reason=f'no real recordings at {REAL}')
def test_the_readme_figures_of_the_freiburg_recording_at_lower_scan_rates():
    """The README's Freiburg paragraph: its 45 Hz `/RAWLASER1` thinned to 22 and 11 Hz,
    on the defaults (walkers' legs become labels of their own) and with the
    `leg_height` preset (counts as at 45 Hz), and the 9 Hz `/ROBOTLASER1` with the
    preset."""
    name, raw = 'freiburg_corridor_stationary_sick', '/RAWLASER1'
    assert thinned_run(name, raw, 2) == (17, '3.86')
    assert thinned_run(name, raw, 4) == (23, '3.96')
    assert thinned_run(name, raw, 1, 'leg_height') == (8, '2.42')
    assert thinned_run(name, raw, 2, 'leg_height') == (7, '2.38')
    assert thinned_run(name, raw, 4, 'leg_height') == (7, '2.40')
    assert thinned_run(name, '/ROBOTLASER1', 1, 'leg_height') == (6, '2.43')
