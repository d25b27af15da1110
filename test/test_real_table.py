"""The README's table of the real recordings is what `make real` gives."""

from pathlib import Path
import re

import pytest

from extended_tracker.cli import _config, REAL_PRESETS, REAL_TOPICS
from extended_tracker.replay import replay

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
