"""The configuration tree: every leaf validated, with the bad value and range in the error."""

from pathlib import Path

import pytest

from extended_tracker.config import (
    from_dict, from_flat, iter_leaves, leaf_kind, to_flat, TrackerConfig,
)
from extended_tracker.configio import load_yaml
from extended_tracker.errors import ConfigError


@pytest.mark.parametrize('flat, message', [
    ({'model.rho': 0.0}, 'model.rho must be > 0.0, got 0.0'),
    ({'model.n_max': 500}, 'model.n_max must be <= 200 objects, got 500'),
    ({'model.n_max': 201}, 'model.n_max must be <= 200 objects, got 201'),
    ({'model.n_max': True}, 'model.n_max must be an integer, got True'),
    ({'partition.d_max': -1.0}, 'partition.d_max must be > 0.0 m, got -1.0'),
    ({'partition.d_min': -0.1}, 'partition.d_min must be >= 0.0 m, got -0.1'),
    ({'model.mode': 'x'}, "model.mode must be one of ('cphd', 'phd'), got 'x'"),
    ({'background.enabled': 'yes'}, 'background.enabled must be true or false'),
    ({'background.enabled': 1}, 'background.enabled must be true or false, got 1'),
    ({'birth.regions': [1.0, 2.0]}, 'x, y, std triples'),
    ({'model.n_max': 2.5}, 'model.n_max must be an integer'),
    ({'model.sigma_accel': float('nan')}, 'must be finite'),
    ({'model.sigma_accel': float('inf')}, 'model.sigma_accel must be finite, got inf'),
    ({'partition.d_min': 0.9, 'partition.d_max': 0.5}, 'd_min (0.9) must not exceed'),
    ({'partition.leg_gap': 0.9, 'partition.d_max': 0.5}, 'leg_gap (0.9) must not exceed'),
    ({'model.rho': '0.25'}, "model.rho must be a number, got '0.25'"),
    ({'model.rho': True}, 'model.rho must be a number, got True'),
    ({'birth.regions': [1.0, 'a', 2.0]}, 'birth.regions must be a list of finite numbers'),
    ({'birth.regions': 3.0}, 'birth.regions must be a list of finite numbers'),
    ({'birth.regions': [1.0, True, 2.0]}, 'birth.regions must be a list of finite numbers'),
    ({'birth.regions': [1.0, 2.0, float('inf')]}, 'birth.regions must be a list of finite'),
])
def test_bad_values_are_refused_with_the_reason(flat, message):
    with pytest.raises(ConfigError) as err:
        from_flat(flat)
    assert message in str(err.value)


def test_unknown_keys_and_sections_are_refused():
    with pytest.raises(ConfigError, match='unknown keys in model'):
        from_dict({'model': {'rhoo': 1.0}})
    with pytest.raises(ConfigError, match='unknown configuration sections'):
        from_dict({'filterr': {}})
    with pytest.raises(ConfigError, match='section.key'):
        from_flat({'rho': 1.0})
    with pytest.raises(ConfigError, match='section model must be a mapping, got 3'):
        from_dict({'model': 3})
    # an empty sequence or a zero is no section either (YAML's bare `model:` is None: the
    # defaults)
    for bad in ([], 0, ''):
        with pytest.raises(ConfigError, match='section model must be a mapping'):
            from_dict({'model': bad})
    assert from_dict({'model': None}) == from_dict({'model': {}}) == TrackerConfig()


def test_round_trips_and_documentation():
    cfg = TrackerConfig()
    assert from_flat(to_flat(cfg)) == cfg
    # ints accepted as floats, and stored as floats: a ROS parameter declared from the
    # value takes its type from it
    rho = from_dict({'model': {'rho': 1}}).model.rho
    assert rho == 1.0 and type(rho) is float
    assert type(from_flat({'model.n_max': 7}).model.n_max) is int
    for name, f, value in iter_leaves(cfg):
        assert f.metadata['description'], name
        # the kind every check and the node's parameter types are read from
        assert leaf_kind(f) == type(value).__name__, name


def _with(flat: dict, name: str, value) -> dict:
    """``flat`` with ``name`` set to ``value``, and d_max raised to its top when d_min or
    leg_gap is set (the checks across fields: neither may exceed d_max)."""
    out = dict(flat, **{name: value})
    if name in ('partition.d_min', 'partition.leg_gap'):
        out['partition.d_max'] = 20.0
    return out


def test_every_numeric_bound_is_where_its_declaration_puts_it():
    """Each number's declared range, read from the field's metadata, is the range taken:
    a closed end accepted and a step past it refused, an open end refused."""
    defaults = to_flat(TrackerConfig())
    checked = 0
    for name, f, value in iter_leaves(TrackerConfig()):
        meta = f.metadata
        if isinstance(value, (bool, str, list)):
            continue
        step = 1 if isinstance(value, int) else 1e-6 * max(1.0, abs(meta['max']))
        lo, hi = meta['min'], meta['max']
        assert to_flat(from_flat(_with(defaults, name, hi)))[name] == hi
        with pytest.raises(ConfigError, match=f'{name} must be <= '):
            from_flat(_with(defaults, name, hi + step))
        if meta['lo_open']:
            with pytest.raises(ConfigError, match=f'{name} must be > '):
                from_flat(_with(defaults, name, lo))
        else:
            assert to_flat(from_flat(_with(defaults, name, lo)))[name] == lo
            with pytest.raises(ConfigError, match=f'{name} must be >= '):
                from_flat(_with(defaults, name, lo - step))
        checked += 1
    assert checked > 60


def test_d_min_may_equal_d_max():
    """One distance threshold is a valid partitioning: d_min only must not exceed d_max."""
    cfg = from_flat({'partition.d_min': 0.5, 'partition.d_max': 0.5})
    assert cfg.partition.d_min == cfg.partition.d_max == 0.5


def test_list_defaults_are_not_shared():
    """Each config holds its own list: growing one config's regions leaves the next
    config's defaults alone."""
    a, b = TrackerConfig(), TrackerConfig()
    assert a.birth.regions == b.birth.regions == [] and a.birth.regions is not b.birth.regions


def test_yaml_errors_are_config_errors(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('model: [1, 2')
    with pytest.raises(ConfigError, match='cannot read config'):
        load_yaml(bad)
    with pytest.raises(ConfigError, match='cannot read config'):
        load_yaml(tmp_path / 'missing.yaml')
    lst = tmp_path / 'list.yaml'
    lst.write_text('- 1\n- 2\n')
    with pytest.raises(ConfigError, match='must be a mapping'):
        load_yaml(lst)
    # one line, with the position: the command line prints it as one error line
    bad.write_text('model: {mode: phd}\n\tx: 1\n')
    with pytest.raises(ConfigError) as err:
        load_yaml(bad)
    assert '\n' not in str(err.value) and 'line 2, column 1' in str(err.value)
    bad.write_text('model:\n  ? [1, 2]\n  : 3\n')
    with pytest.raises(ConfigError, match='found unhashable key'):
        load_yaml(bad)


def test_plain_yaml_reads_numbers_and_repeated_sections_as_a_parameter_file_does(tmp_path):
    """The plain sections are read with the parameter file's rules (test_node holds those
    to the node's own reading): exponents are numbers, y/n booleans, a section written
    twice merged with the later value winning. PyYAML alone refused 1e-5 as a string and
    kept only the second model section, dropping the first one's n_max."""
    path = tmp_path / 'c.yaml'
    path.write_text('model:\n  n_max: 30\n  mode: cphd\nreduction: {prune_weight: 1e-5}\n'
                    'background: {enabled: n}\nmodel:\n  mode: phd\n')
    cfg = load_yaml(path)
    assert (cfg.model.n_max, cfg.model.mode) == (30, 'phd')
    assert cfg.reduction.prune_weight == 1e-5 and cfg.background.enabled is False
    path.write_text('model: {clutter_rate: 3E1, rho: -1e+0}\n')
    with pytest.raises(ConfigError, match='model.rho must be > 0'):   # read as a number
        load_yaml(path)
    path.write_text('model: {clutter_rate: 3E1}\nbirth: {regions: [1e0, 2, 5e-1]}\n')
    cfg = load_yaml(path)
    assert cfg.model.clutter_rate == 30.0 and cfg.birth.regions == [1.0, 2.0, 0.5]
    # every decimal form strtod reads whole (YAML 1.1 wants a point and a signed exponent)
    path.write_text('birth: {regions: [1.5e1, 5.e-1, -2.5E0, .5e1, +1e0, 1.5e+1]}\n')
    assert load_yaml(path).birth.regions == [15.0, 0.5, -2.5, 5.0, 1.0, 15.0]


def test_presets_and_their_yaml_files_agree():
    """config/<preset>.yaml is generated from PRESETS and changes exactly those keys."""
    from extended_tracker.config import preset, PRESETS
    from extended_tracker.configio import preset_yaml

    root = Path(__file__).resolve().parents[1]
    defaults = to_flat(TrackerConfig())
    for name, changes in PRESETS.items():
        path = root / 'config' / f'{name}.yaml'
        assert path.read_text() == preset_yaml(name), f'config/{name}.yaml is stale: make config'
        cfg = preset(name)
        assert load_yaml(path) == cfg
        changed = {k for k, v in to_flat(cfg).items() if v != defaults[k]}
        assert changed == {f'{sec}.{key}' for sec, kv in changes.items() for key in kv}
    with pytest.raises(ConfigError, match='unknown preset'):
        preset('nope')


def test_every_field_is_read_by_the_package():
    """A proxy for "every parameter does something": each field's name is read as an
    attribute somewhere in the package outside the configuration module (the dead
    ``birth.position_std`` sat in the parameters from the first commit on)."""
    import re

    root = Path(__file__).resolve().parents[1] / 'extended_tracker'
    source = '\n'.join(p.read_text() for p in root.rglob('*.py') if p.name != 'config.py')
    unread = [name for name, _, _ in iter_leaves(TrackerConfig())
              if not re.search(r'\.' + name.split('.')[-1] + r'\b', source)]
    assert unread == []


def test_the_readme_parameter_table_is_generated_from_the_descriptors():
    """Every parameter of the node in the README's table, with the default, unit, range and
    description the descriptors carry (`make config` writes it)."""
    from pathlib import Path

    from extended_tracker.config import iter_leaves
    from extended_tracker.configio import parameter_table, PARAMETERS_BEGIN, PARAMETERS_END

    text = (Path(__file__).resolve().parents[1] / 'README.md').read_text()
    table = text.split(PARAMETERS_BEGIN)[1].split(PARAMETERS_END)[0].strip()
    assert table == parameter_table(), 'run `make config` and commit README.md'
    rows = table.splitlines()[2:]
    assert [r.split('`')[1] for r in rows] == [name for name, _, _ in iter_leaves(TrackerConfig())]
    assert '| `model.n_max` | `40` | objects, [1, 200] | cardinality pmf truncated' in table
