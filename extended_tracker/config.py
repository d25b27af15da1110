"""
Configuration: one validated dataclass tree, the single source of truth.

Every leaf field carries its description, unit and range in ``metadata``; the YAML in
``config/`` and the ROS parameter descriptors are generated from or checked against it.
Flat names join the tree with dots (``model.mode``, ``partition.d_max``).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
import math
from typing import Any

from .errors import ConfigError


def _f(default, description, unit='', lo=None, hi=None, choices=None, lo_open=False):
    """Declare a leaf field with its documentation and valid range."""
    meta = {'description': description, 'unit': unit, 'min': lo, 'max': hi,
            'choices': choices, 'lo_open': lo_open}
    if isinstance(default, (list, tuple)):
        return field(default_factory=lambda: list(default), metadata=meta)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class ModelConfig:
    """Multi-object filter: mode, cardinality, motion and measurement model."""

    mode: str = _f('cphd', 'multi-object update: cphd, or phd (its Poisson special case)',
                   choices=('cphd', 'phd'))
    n_max: int = _f(40, 'cardinality pmf truncated at this many objects', 'objects', 1, 200)
    p_survival: float = _f(0.99, 'probability an object survives one second', '', 0.0, 1.0,
                           lo_open=True)
    sigma_accel: float = _f(2.0, 'white acceleration noise of the CV model', 'm/s^2', 0.0, 50.0,
                            lo_open=True)
    tau_rate: float = _f(2.0, 'time constant of measurement-rate forgetting', 's', 0.0, 1e4,
                         lo_open=True)
    tau_extent: float = _f(2.0, 'time constant of extent forgetting', 's', 0.0, 1e4,
                           lo_open=True)
    rho: float = _f(0.25, 'scale of the extent in the measurement spread (rho X + R)', '',
                    0.0, 4.0, lo_open=True)
    sigma_range: float = _f(0.03, 'std of the sensor noise R = sigma^2 I', 'm', 0.0, 2.0,
                            lo_open=True)
    clutter_rate: float = _f(1.0, 'mean number of clutter detections per scan (Poisson)',
                             'detections', 0.0, 1e4, lo_open=True)
    clutter_memory: float = _f(3.0, 'memory of the clutter rate learned from the scans; the '
                               'filter assumes the larger of it and clutter_rate (0: off)',
                               's', 0.0, 1e4)
    surveillance_area: float = _f(100.0, 'clutter area when the scan does not give one', 'm^2',
                                  0.0, 1e8, lo_open=True)
    clutter_density: str = _f('area', 'where clutter falls: area (uniform over the field of '
                              'view), or beam (on a random beam at a uniform range: denser '
                              'near the scanner, as a laser\'s spurious returns)',
                              choices=('area', 'beam'))


@dataclass(frozen=True)
class DetectionConfig:
    """Probability of detection."""

    model: str = _f('scan_shadow', 'p_D model: scan_shadow, estimate_shadow or constant',
                    choices=('scan_shadow', 'estimate_shadow', 'constant'))
    p_d0: float = _f(0.95, 'probability of detection of an object in full view', '', 0.0, 1.0,
                     lo_open=True)
    shadow_margin: float = _f(0.3, 'a return this much nearer than the object shadows it', 'm',
                              0.0, 10.0)
    widen_sigmas: float = _f(1.0, 'angular interval widened by this many position stds', '',
                             0.0, 5.0)
    max_widen: float = _f(0.3, 'most the position uncertainty widens the interval', 'm', 0.0,
                          10.0)
    scale_rate_by_visibility: bool = _f(True, 'expected detections scaled by the visible '
                                        'fraction')
    min_visibility: float = _f(0.05, 'visible fraction below which an object counts as hidden',
                               '', 0.0, 1.0)
    hold_hidden: bool = _f(True, 'a confirmed track whose own extent is wholly in shadow, '
                           'with no return on its predicted outline, is not worn down by '
                           'misses')
    min_fill: float = _f(0.1, 'a component, or a birth on returns no track explains, in view '
                         'and expecting fewer returns than this share of the beams its '
                         'extent spans is dropped: no solid object (0: never)',
                         'returns per beam', 0.0, 1.0)


@dataclass(frozen=True)
class PartitionConfig:
    """Measurement partitioning and gating."""

    d_min: float = _f(0.2, 'smallest distance threshold of distance partitioning until the '
                      'scans show legs', 'm', 0.0, 10.0)
    leg_gap: float = _f(0.45, 'once the scans show legs (a scanner at leg height, '
                        'doc/model.md 5), the smallest threshold is at least this, over a '
                        'walker\'s two legs (0: never)', 'm', 0.0, 10.0)
    d_max: float = _f(0.8, 'largest distance threshold of distance partitioning', 'm', 0.0,
                      20.0, lo_open=True)
    max_partitions: int = _f(40, 'cap on the number of partitions per scan', '', 1, 10000)
    max_cells: int = _f(600, 'cap on the number of distinct cells per scan (the first '
                        'partition is taken whatever its cells)', '', 1, 100000)
    sub_partition: bool = _f(True, 'split cells that likely hold several objects (k-means++)')
    max_sub_objects: int = _f(4, 'most objects sub-partitioning splits one cell into', '', 2,
                              20)
    prediction_partition: bool = _f(True, 'add a partition from the gates of confident tracks')
    split_small: int = _f(2, 'a cell of the finest distance partition with 2 up to this many '
                          'detections is also tried as lone returns (clutter), one partition '
                          'each (below 2: never)', 'detections', 0, 1000)
    gate_probability: float = _f(0.999, 'chi-square gate probability of (component, cell); 1: '
                                 'no gate', '', 0.5, 1.0, lo_open=True)


@dataclass(frozen=True)
class BirthConfig:
    """Birth: a uniform birth intensity evaluated per cell, and configured birth regions."""

    rate: float = _f(0.5, 'expected number of objects appearing per second, anywhere',
                     'objects/s', 0.0, 1e3, lo_open=True)
    min_weight: float = _f(0.02, 'birth hypotheses lighter than this are dropped', '', 0.0, 1.0)
    min_points: int = _f(2, 'fewest detections a new object is born from (a lone point is '
                         'indistinguishable from clutter; fewer that no object explains '
                         'are clutter)', 'detections', 1, 1000)
    velocity_std: float = _f(1.5, 'velocity std of a new object', 'm/s', 0.0, 50.0,
                             lo_open=True)
    dof: float = _f(20.0, 'inverse Wishart v of the birth extent prior (> 6)', '', 6.0, 1e5,
                    lo_open=True)
    extent_semi_axis: float = _f(0.25, 'semi-axis of the birth extent prior mean (circle)', 'm',
                                 0.0, 10.0, lo_open=True)
    rate_shape: float = _f(1.0, 'Gamma alpha of the birth measurement rate', '', 0.0, 1e5,
                           lo_open=True)
    expected_rate: float = _f(10.0, 'mean detections per scan of a new object', 'detections',
                              0.0, 1e5, lo_open=True)
    weight: float = _f(0.1, 'weight of each birth-region component per scan', '', 0.0, 1.0,
                       lo_open=True)
    regions: list = _f([], 'birth regions, flat list of x, y, std triples', 'm')


@dataclass(frozen=True)
class ReductionConfig:
    """Pruning, merging and capping of the mixture."""

    prune_weight: float = _f(1e-3, 'components lighter than this are dropped', '', 0.0, 1.0)
    merge_distance: float = _f(4.0, 'squared Mahalanobis distance for merging one label', '',
                               0.0, 1e4)
    max_components: int = _f(150, 'cap on the number of components', '', 1, 100000)
    max_semi_axis: float = _f(4.0, 'components with a larger semi-major axis are dropped '
                              '(walls, not objects)', 'm', 0.0, 1000.0, lo_open=True)
    max_position_std: float = _f(3.0, 'components whose position std grew beyond this are '
                                 'dropped', 'm', 0.0, 1000.0, lo_open=True)
    max_open_position_std: float = _f(6.0, 'max_position_std for those with no background in '
                                      'front (hidden by people, not walls)', 'm', 0.0, 1000.0,
                                      lo_open=True)
    fuse_weight: float = _f(1.5, 'two labels on one spot (within merge_distance) whose weights '
                            'sum to at most this are one object and get one label (0: never)',
                            '', 0.0, 10.0)
    split_weight: float = _f(0.4, 'a far component of a label this heavy gets a new label, a '
                             'lighter one is dropped', '', 0.0, 10.0)
    pair_scans: int = _f(3, 'two labels at most pair_distance apart, one of them part-sized '
                         '(a leg), in this many scans in a row are one object seen as two and '
                         'become one track (0: never)', 'scans', 0, 100000)
    pair_distance: float = _f(0.6, 'how near the centres of a pair stay', 'm', 0.0, 10.0)
    pair_speed: float = _f(2.5, 'how much the velocities of a pair differ at most (one leg '
                           'swings while the other stands)', 'm/s', 0.0, 100.0)
    pair_semi_axis: float = _f(0.28, 'largest semi-major axis of a part', 'm', 0.0, 10.0)


@dataclass(frozen=True)
class ExtractionConfig:
    """Which labels are reported and how they are drawn."""

    min_existence: float = _f(0.3, 'labels lighter than this are never reported', '', 0.0, 1.0)
    phd_threshold: float = _f(0.5, 'phd mode reports labels heavier than this', '', 0.0, 1.0)
    confirm_scans: int = _f(3, 'scans in a row a label must be extracted before it is reported',
                            '', 1, 1000)
    confirm_detections: int = _f(3, 'and in how many of those scans returns must have updated '
                                 'it (its birth scan counts; 0: the scans alone)', '', 0, 1000)
    max_speed: float = _f(15.0, 'a report farther than max_speed times the time since its id '
                          'was last shown (plus jump_slack) is a new object: it gets a new id',
                          'm/s', 0.0, 1000.0, lo_open=True)
    max_accel: float = _f(10.0, 'a report farther than max_accel t^2 / 2 (plus jump_slack) '
                          'from where its id\'s last shown velocity would have carried it in '
                          't seconds is a new object (0: no check)', 'm/s^2', 0.0, 1000.0)
    jump_slack: float = _f(1.0, 'allowance on top of max_speed and max_accel for the spread '
                           'of an estimate between partial views', 'm', 0.0, 100.0)
    handover_time: float = _f(1.5, 'an id shown until this long ago and lost passes to an '
                              'object first extracted this recently near where it was (0: never)',
                              's', 0.0, 100.0)
    handover_distance: float = _f(0.8, 'how near the lost id\'s extrapolated position the new '
                                  'object must be', 'm', 0.0, 100.0)
    group_gap: float = _f(0.5, 'thin contour pieces (a car\'s side and its end), one ending this '
                          'close to the other and moving alike (group_speed), are one object '
                          '(0: never)', 'm', 0.0, 10.0)
    group_speed: float = _f(2.0, 'how closely grouped pieces\' velocities agree, beyond half '
                            'the faster\'s speed', 'm/s', 0.0, 100.0)
    rectangle_length: float = _f(1.2, 'objects longer than this are drawn as rectangles', 'm',
                                 0.0, 100.0)
    rectangle_elongation: float = _f(2.5, 'or more elongated than this (semi-axes ratio) and '
                                     'at least half that long', '', 1.0, 100.0)
    marker_lifetime: float = _f(1.0, 'RViz drops markers this long after they were last '
                                'sent: a node that stops leaves no ghosts (0: kept until '
                                'deleted)', 's', 0.0, 3600.0)


@dataclass(frozen=True)
class ScanConfig:
    """Scan conversion."""

    min_range: float = _f(0.0, 'extra lower range limit on top of the scan range_min', 'm', 0.0,
                          1000.0)
    max_range: float = _f(0.0, 'extra upper range limit (0: only the scan range_max)', 'm', 0.0,
                          1000.0)
    range_max_inclusive: bool = _f(False, 'keep returns exactly at range_max (drivers often '
                                   'report no return as range_max)')


@dataclass(frozen=True)
class BackgroundConfig:
    """Static background learned per beam for a stationary sensor."""

    enabled: bool = _f(True, 'learn and drop the static background (doc/model.md 7b)')
    margin: float = _f(0.15, 'a return within this of the background range is background',
                       'm', 0.0, 10.0)
    learn_time: float = _f(2.0, 'time constant of learning a beam background', 's', 0.0, 1e4,
                           lo_open=True)
    forget_time: float = _f(30.0, 'time for a background beam to forget a removed object', 's',
                            0.0, 1e5, lo_open=True)
    confirm_time: float = _f(1.0, 'a beam must return the same range this long to be background',
                             's', 0.0, 1e4)
    warmup: float = _f(1.5, 'after start-up only learn the background this long (objects '
                       'and newcomers are tracked)', 's', 0.0, 1e4)
    object_size: float = _f(1.0, 'returns this small that nothing nearer hides are an object '
                            '(a person, a chair): tracked from start-up (0: none)', 'm', 0.0,
                            10.0)
    object_time: float = _f(30.0, 'an object standing still this long is learned (0: never)',
                            's', 0.0, 1e5)
    track_gate: float = _f(0.5, 'returns this close to a protecting track are never learned',
                           'm', 0.0, 10.0)
    moved_distance: float = _f(0.5, 'a confirmed track protects its returns from being '
                               'learned once it has moved this far beyond its first extent '
                               'while seen (a person)', 'm', 0.0, 100.0)
    protect_semi_axis: float = _f(0.6, 'only tracks this small (semi-major) protect returns: '
                                  'people, not walls', 'm', 0.0, 100.0)
    map_cell: float = _f(0.1, 'cell of the static map learned in the fixed frame while the '
                         'scanner moves', 'm', 0.02, 1.0)
    map_radius: float = _f(15.0, 'the static map reaches this far round the scanner (returns '
                           'beyond it are never static)', 'm', 1.0, 100.0)


@dataclass(frozen=True)
class TimeConfig:
    """Handling of scan stamps."""

    max_gap: float = _f(2.0, 'a gap longer than this re-initialises the filter', 's', 0.0, 1e5,
                        lo_open=True)
    default_dt: float = _f(0.1, 'dt of the first scan after a reset', 's', 0.0, 10.0,
                           lo_open=True)
    latency: float = _f(0.05, 'several scanners: a scan waits this long for earlier-stamped '
                        'ones', 's', 0.0, 2.0)


@dataclass(frozen=True)
class TfConfig:
    """The fixed frame the tracks are kept in, and the transforms into it."""

    fixed_frame: str = _f('odom', 'frame the tracks are kept and published in (the scanner '
                          'may move in it); empty: the scan frame')
    timeout: float = _f(0.2, 'how long a scan waits for its transform to the fixed frame',
                        's', 0.0, 10.0)
    max_tilt: float = _f(0.1, 'a scan plane tilted more than this from the fixed frame\'s '
                         'plane is refused; less is projected onto it', 'rad', 0.0, 1.5)
    jump_speed: float = _f(10.0, 'the scanner moving faster than this between two scans is a '
                           'jump of the fixed frame (a localisation reset): tracks restart',
                           'm/s', 0.0, 1e4, lo_open=True)
    jump_turn_rate: float = _f(6.3, 'or turning faster than this', 'rad/s', 0.0, 1e4,
                               lo_open=True)


@dataclass(frozen=True)
class TrackerConfig:
    """Everything the per-scan pipeline needs."""

    model: ModelConfig = field(default_factory=ModelConfig)
    detection: DetectionConfig = field(default_factory=DetectionConfig)
    partition: PartitionConfig = field(default_factory=PartitionConfig)
    birth: BirthConfig = field(default_factory=BirthConfig)
    reduction: ReductionConfig = field(default_factory=ReductionConfig)
    extraction: ExtractionConfig = field(default_factory=ExtractionConfig)
    scan: ScanConfig = field(default_factory=ScanConfig)
    background: BackgroundConfig = field(default_factory=BackgroundConfig)
    timing: TimeConfig = field(default_factory=TimeConfig)
    tf: TfConfig = field(default_factory=TfConfig)

    def __post_init__(self):
        validate(self)


def _check_leaf(name: str, value: Any, f) -> None:
    meta = f.metadata
    expected = leaf_kind(f)
    if expected == 'bool':
        if not isinstance(value, bool):
            raise ConfigError(f'{name} must be true or false, got {value!r}')
        return
    if expected == 'str':
        if not isinstance(value, str) or (meta['choices'] and value not in meta['choices']):
            raise ConfigError(f'{name} must be one of {meta["choices"]}, got {value!r}')
        return
    if expected == 'list':
        if not isinstance(value, (list, tuple)) or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                for v in value):
            raise ConfigError(f'{name} must be a list of finite numbers, got {value!r}')
        if name.endswith('regions') and len(value) % 3:
            raise ConfigError(f'{name} holds x, y, std triples; got {len(value)} numbers')
        return
    if expected == 'int' and (isinstance(value, bool) or not isinstance(value, int)):
        raise ConfigError(f'{name} must be an integer, got {value!r}')
    if expected == 'float':
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f'{name} must be a number, got {value!r}')
        if not math.isfinite(value):
            raise ConfigError(f'{name} must be finite, got {value!r}')
    lo, hi = meta['min'], meta['max']
    unit = f' {meta["unit"]}' if meta['unit'] else ''
    if lo is not None and (value < lo or (meta['lo_open'] and value == lo)):
        op = '>' if meta['lo_open'] else '>='
        raise ConfigError(f'{name} must be {op} {lo}{unit}, got {value!r}')
    if hi is not None and value > hi:
        raise ConfigError(f'{name} must be <= {hi}{unit}, got {value!r}')


def validate(cfg: TrackerConfig) -> None:
    """
    Check every leaf of ``cfg`` against its declared type and range.

    Raises
    ------
    ConfigError
        Naming the first bad field, its valid range and the value given.

    """
    for path, f, value in iter_leaves(cfg):
        _check_leaf(path, value, f)
    if cfg.partition.d_min > cfg.partition.d_max:
        raise ConfigError(f'partition.d_min ({cfg.partition.d_min}) must not exceed '
                          f'partition.d_max ({cfg.partition.d_max})')
    if cfg.partition.leg_gap > cfg.partition.d_max:
        raise ConfigError(f'partition.leg_gap ({cfg.partition.leg_gap}) must not exceed '
                          f'partition.d_max ({cfg.partition.d_max})')


def leaf_kind(f) -> str:
    """A leaf field's type as a name: 'bool', 'int', 'float', 'str' or 'list' (the
    annotation itself: this module's annotations are strings, under ``from __future__
    import annotations``)."""
    return f.type


def iter_leaves(cfg, prefix=''):
    """Yield ``(dotted_name, dataclass_field, value)`` for every leaf of ``cfg``."""
    for f in fields(cfg):
        value = getattr(cfg, f.name)
        name = f'{prefix}{f.name}'
        if is_dataclass(value):
            yield from iter_leaves(value, name + '.')
        else:
            yield name, f, value


def to_dict(cfg: TrackerConfig) -> dict:
    """Nested plain dict of ``cfg``."""
    return asdict(cfg)


def to_flat(cfg: TrackerConfig) -> dict[str, Any]:
    """Flat ``{'model.mode': 'cphd', ...}`` view of ``cfg``."""
    return {name: value for name, _, value in iter_leaves(cfg)}


def from_dict(data: dict | None) -> TrackerConfig:
    """
    Build a validated config from a nested dict; unknown keys are refused.

    Raises
    ------
    ConfigError
        On an unknown section or key, or a bad value.

    """
    data = dict(data or {})
    base = TrackerConfig()
    sections = {}
    for f in fields(base):
        sub = data.pop(f.name, None)
        if sub is None:
            continue
        if not isinstance(sub, dict):
            raise ConfigError(f'section {f.name} must be a mapping, got {sub!r}')
        known = {g.name: g for g in fields(getattr(base, f.name))}
        unknown = set(sub) - set(known)
        if unknown:
            raise ConfigError(f'unknown keys in {f.name}: {sorted(unknown)}')
        coerced = {}
        for key, val in sub.items():
            kind = leaf_kind(known[key])
            if kind == 'float' and isinstance(val, int) and not isinstance(val, bool):
                val = float(val)
            coerced[key] = val
        sections[f.name] = replace(getattr(base, f.name), **coerced)
    if data:
        raise ConfigError(f'unknown configuration sections: {sorted(data)}')
    return replace(base, **sections)


def from_flat(flat: dict[str, Any]) -> TrackerConfig:
    """Build a validated config from dotted names (as ROS parameters give them)."""
    nested: dict[str, dict] = {}
    for name, value in flat.items():
        section, _, key = name.partition('.')
        if not key:
            raise ConfigError(f'parameter {name!r} is not of the form section.key')
        nested.setdefault(section, {})[key] = value
    return from_dict(nested)


# Named sets of changes from the defaults, for installations the defaults do not fit.
# ``config/<name>.yaml`` is generated from these (``make config``); a test keeps them equal.
PRESETS: dict[str, dict] = {
    # The defaults serve a scanner at any height: leg pairs are joined (pair_scans,
    # pair_semi_axis), the legs are offered as one cell once the scans show legs (leg_gap;
    # told the height, from the first scan: d_min), and an id is shown only
    # after returns in three scans (confirm_detections), which keeps stray leg-sized returns
    # (chair legs, a half-hidden wall edge) from being shown. What is left for a scanner at
    # leg height is that it sees people only: an id moves at walking speed, not a car's,
    # and max_speed 3 m/s gives a new id where a coasting track would take over a newcomer
    # 4-9 m away (leg_tracker positive_1 and demo recordings).
    'leg_height': {'partition': {'d_min': 0.45}, 'extraction': {'max_speed': 3.0}},
}


def preset(name: str) -> TrackerConfig:
    """The defaults with the changes of preset ``name`` (see :data:`PRESETS`)."""
    if name not in PRESETS:
        raise ConfigError(f'unknown preset {name!r}; known: {sorted(PRESETS)}')
    return from_dict(PRESETS[name])
