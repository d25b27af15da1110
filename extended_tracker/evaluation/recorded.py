"""
Score a replay of a recording that has motion-capture truth (``../shared/data/moving``:
``<bag>.ground_truth.csv`` beside each bag, one row per scan and target in the fixed
frame) : how often each target that the scan sees is tracked, how far off, and by how
many ids.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..bag.replay import choose_fixed_frame, replay_results
from ..config import TrackerConfig

#: a target is seen in a scan with at least this many returns within 0.3 m of it
SEEN_RETURNS = 3
#: an estimate this near a target (m) tracks it
MATCH_DISTANCE = 0.5


@dataclass
class TargetScore:
    seen: int = 0                       # scans the target was seen in
    tracked: int = 0                    # of those, scans an estimate tracked it in
    errors: list = field(default_factory=list)
    ids: set = field(default_factory=set)

    def line(self, name: str) -> str:
        err = np.mean(self.errors) if self.errors else float('nan')
        return (f'{name:12s} tracked {self.tracked}/{self.seen} scans seen, mean position '
                f'error {err:.2f} m, {len(self.ids)} id(s)')


def read_truth(path) -> dict[int, dict[str, np.ndarray]]:
    """``{scan_stamp_ns: {target: (x, y), ...}}`` of the scans each target is seen in."""
    out: dict = {}
    with open(path, newline='') as f:
        for row in csv.DictReader(f):
            if int(row['n_returns_0p3']) < SEEN_RETURNS:
                continue
            out.setdefault(int(row['scan_stamp_ns']), {})[row['target']] = np.array(
                [float(row['x_map']), float(row['y_map'])])
    return out


def score_recording(bag, truth_csv, cfg: TrackerConfig | None = None):
    """``({target: TargetScore}, unmatched estimates per scan, frame)``: the bag replayed
    in its fixed frame (``tf.fixed_frame``) and scored against the truth."""
    cfg = cfg or TrackerConfig()
    truth = read_truth(truth_csv)
    frame = choose_fixed_frame(bag, None, cfg)[0]
    scores: dict[str, TargetScore] = {}
    unmatched, scans = 0, 0
    for _, res in replay_results(bag, cfg, None, None, frame):
        scans += 1
        seen = truth.get(res.stamp_ns, {})
        names = sorted(seen)
        est = res.estimates
        if names and len(est):
            t = np.array([seen[n] for n in names])
            d = np.linalg.norm(t[:, None, :] - est.m[None, :, :2], axis=2)
            rows, cols = linear_sum_assignment(np.minimum(d, MATCH_DISTANCE * 2))
            pairs = [(i, j) for i, j in zip(rows, cols) if d[i, j] <= MATCH_DISTANCE]
        else:
            pairs = []
        for n in names:
            scores.setdefault(n, TargetScore()).seen += 1
        for i, j in pairs:
            s = scores[names[i]]
            s.tracked += 1
            s.errors.append(float(d[i, j]))
            s.ids.add(int(est.label[j]))
        unmatched += len(est) - len(pairs)
    return scores, unmatched / max(scans, 1), frame


MOVING = Path('../shared/data/moving')      # from the repository's root, as make runs
BEGIN, END = '<!-- recorded:begin -->', '<!-- recorded:end -->'


def recorded_table(folder=MOVING) -> str:
    """The table of every recording with truth in ``folder``: per target, the scans it
    was tracked in of those the scan saw it in, the mean position error and the ids;
    per recording, the estimates matching no target (other objects, walls, clutter)."""
    lines = ['| recording | target | tracked / seen (scans) | mean error (m) | ids | '
             'other estimates per scan |', '|---|---|---|---|---|---|']
    for csv_path in sorted(Path(folder).glob('*.ground_truth.csv')):
        bag = csv_path.with_name(csv_path.name.removesuffix('.ground_truth.csv'))
        scores, others, frame = score_recording(bag, csv_path)
        for name, s in sorted(scores.items()):
            err = np.mean(s.errors) if s.errors else float('nan')
            lines.append(f'| {bag.name} | {name} | {s.tracked} / {s.seen} | {err:.2f} | '
                         f'{len(s.ids)} | {others:.2f} |')
    return '\n'.join(lines)


def write_recorded_results(path: Path, folder=MOVING) -> bool:
    """Replace the recorded-truth section of ``path`` between its markers; False (and
    nothing written) where ``folder`` holds no recordings or ``path`` has no section."""
    text = path.read_text()
    if BEGIN not in text or END not in text or not any(Path(folder).glob('*.ground_truth.csv')):
        return False
    head, rest = text.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    path.write_text(f'{head}{BEGIN}\n{recorded_table(folder)}\n{END}{tail}')
    return True


def main(folder=MOVING) -> None:
    """Print the table of every recording in ``folder``."""
    print(recorded_table(folder))


if __name__ == '__main__':
    main()
