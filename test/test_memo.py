"""
``memo.evolve`` against ``dataclasses.replace`` on the state objects it stands in for, and
``memo.cached_attribute`` against ``functools.cached_property``.
"""

import dataclasses
import functools
import inspect

import numpy as np
import pytest

from extended_tracker.config import from_dict
from extended_tracker.ggiw import IW_OFFSET, Mixture
from extended_tracker.memo import cached_attribute, evolve
from extended_tracker.pipeline import PipelineState
from extended_tracker.sensing.shadow import Visibility
from extended_tracker.state import Estimates, FilterState


def _mixture():
    k = 3
    V = (10.0 - IW_OFFSET) * np.repeat((0.3 ** 2 * np.eye(2))[None], k, axis=0)
    return Mixture(np.array([0.9, 0.5, 0.2]), np.full(k, 20.0), np.full(k, 2.0),
                   np.arange(4 * k, dtype=float).reshape(k, 4),
                   np.repeat(np.eye(4)[None], k, axis=0), np.full(k, 10.0), V,
                   np.array([1, 1, 2]))


def _same(a, b):
    assert type(a) is type(b)
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            assert x is y or np.array_equal(x, y)
        else:
            assert x is y or x == y


@pytest.mark.parametrize('make, changes', [
    (_mixture, {'w': np.ones(3)}),
    (_mixture, {'label': np.array([4, 5, 6])}),
    (lambda: FilterState.initial(from_dict({})), {'next_label': 7, 'dt': 0.05}),
    (lambda: PipelineState.initial(from_dict({})), {'scans': 3, 'elapsed': 0.3}),
    (lambda: Visibility(np.ones(2), np.ones(2), None), {'p_d': np.zeros(2)}),
    (Estimates.empty, {'label': np.zeros(0, np.int64)}),
])
def test_evolve_equals_replace(make, changes):
    obj = make()
    _same(evolve(obj, **changes), dataclasses.replace(obj, **changes))
    _same(evolve(obj), dataclasses.replace(obj))


@pytest.mark.parametrize('cls', [Mixture, FilterState, PipelineState, Visibility, Estimates])
def test_evolved_classes_only_store_their_fields(cls):
    """What evolve skips (``__init__``) must have nothing else to do."""
    assert not hasattr(cls, '__post_init__')
    # no InitVar (an extra parameter) and no init=False field (a missing one)
    params = list(inspect.signature(cls.__init__).parameters)[1:]
    assert params == [f.name for f in dataclasses.fields(cls)]


def test_evolve_rejects_unknown_fields_and_leaves_cached_properties_behind():
    mix = _mixture()
    with pytest.raises(TypeError, match='no field'):
        evolve(mix, weight=np.ones(3))
    before = mix.expected_extent()                 # cached on mix
    wider = evolve(mix, V=2 * mix.V)
    assert np.allclose(wider.expected_extent(), 2 * before)
    assert np.array_equal(mix.expected_extent(), before)


def test_cached_attribute_computes_once_like_cached_property():
    """On a frozen dataclass, as the package uses it: the first access computes and
    stores, later ones read the stored value without calling the function, the class
    gives the descriptor, and the two decorators agree access by access."""
    calls = []

    def twice(self):
        """Twice x."""
        calls.append(1)
        return self.x * 2.0

    @dataclasses.dataclass(frozen=True)
    class Lean:
        x: float
        spread = cached_attribute(twice)

    @dataclasses.dataclass(frozen=True)
    class Std:
        x: float
        spread = functools.cached_property(twice)

    for cls in (Lean, Std):
        calls.clear()
        a, b = cls(1.5), cls(4.0)
        assert 'spread' not in a.__dict__
        assert (a.spread, a.spread, b.spread) == (3.0, 3.0, 8.0)
        assert len(calls) == 2 and a.__dict__['spread'] == 3.0
        assert isinstance(cls.spread, (cached_attribute, functools.cached_property))
    assert Lean.spread.__doc__ == 'Twice x.' and Lean.spread.name == 'spread'


def test_array_constants_give_what_python_scalars_give():
    """memo.constants and memo.int_constants stand in for Python scalars in array
    expressions: 0-d, read-only, and the same values and dtypes come out of float64 and
    int64 arrays as with the scalars they replace (NEP 50: a Python scalar takes the
    array's dtype; a 0-d float64 array keeps float64 arrays float64, a 0-d int64 array
    keeps int64 ones int64)."""
    from extended_tracker.memo import constants, HALF, int_constants, ONE_I, TWO, ZERO_I

    rng = np.random.default_rng(5)
    x = rng.normal(size=50) * 1e3
    n = rng.integers(-20, 20, size=50)
    for c, value in [(HALF, 0.5), (TWO, 2.0)] + list(zip(constants(1e-9, 3), [1e-9, 3.0])):
        assert c.shape == () and c.dtype == np.float64 and not c.flags.writeable
        for got, want in [(x * c, x * value), (x / c, x / value), (c - x, value - x),
                          (n * c, n * value), (x < c, x < value)]:
            assert got.dtype == want.dtype
            np.testing.assert_array_equal(got, want)
    for c, value in [(ZERO_I, 0), (ONE_I, 1)] + list(zip(int_constants(4, -3), [4, -3])):
        assert c.shape == () and c.dtype == np.int64 and not c.flags.writeable
        for got, want in [(n + c, n + value), (n >= c, n >= value), (n * c, n * value)]:
            assert got.dtype == want.dtype
            np.testing.assert_array_equal(got, want)


def _lean_classes():
    from extended_tracker.cphd import UpdateWeights
    from extended_tracker.ggiw import CellStats, PairUpdate
    from extended_tracker.sensing.background import BackgroundState
    from extended_tracker.sensing.scan import ScanPoints
    return [Mixture, CellStats, PairUpdate, UpdateWeights, Estimates, Visibility, ScanPoints,
            BackgroundState]


@pytest.mark.parametrize('cls', _lean_classes())
def test_lean_init_builds_what_the_dataclass_init_builds(cls):
    """memo.lean_init: the same parameters and defaults, the same fields stored (by
    position or keyword, defaults left out or not), still frozen, still equal."""
    from extended_tracker.memo import lean_init  # noqa: F401 (what is tested)
    fields = dataclasses.fields(cls)
    native = cls.__init__.dataclass_init
    assert (inspect.signature(cls.__init__).parameters.keys()
            == inspect.signature(native).parameters.keys())
    for name, p in inspect.signature(native).parameters.items():
        assert inspect.signature(cls.__init__).parameters[name].default == p.default
    values = [object() for _ in fields]
    required = [f for f in fields if f.default is dataclasses.MISSING]
    for args, kwargs in [(values, {}), ([], {f.name: v for f, v in zip(fields, values)}),
                         (values[:len(required)], {})]:
        lean = cls(*args, **kwargs)
        ref = object.__new__(cls)
        native(ref, *args, **kwargs)
        assert lean.__dict__ == ref.__dict__
        assert [getattr(lean, f.name) for f in fields] == [getattr(ref, f.name)
                                                          for f in fields]
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(lean, fields[0].name, 1)
    with pytest.raises(TypeError):
        cls(*values, values[0])                       # one argument too many
    with pytest.raises(TypeError):
        cls(*values[:len(required) - 1])              # one required argument missing


@pytest.mark.parametrize('extra', [
    'y: list = dataclasses.field(default_factory=list)',
    'y: int = dataclasses.field(default=0, init=False)',
    'y: int = dataclasses.field(default=0, kw_only=True)',
    'y: dataclasses.InitVar[int] = 0',
    'def __post_init__(self):\n        pass',
])
def test_lean_init_refuses_an_init_that_does_more_than_store(extra):
    from extended_tracker.memo import lean_init
    namespace = {'dataclasses': dataclasses}
    exec(f'@dataclasses.dataclass(frozen=True)\nclass C:\n    x: int\n    {extra}\n',
         namespace)
    with pytest.raises(TypeError, match='does more than store'):
        lean_init(namespace['C'])


def test_all_of_and_any_of_give_all_and_any():
    """memo.all_of / any_of stand in for ``np.logical_and.reduce`` / ``logical_or.reduce``
    on 1-D arrays and ``a.all()`` / ``a.any()`` on any: booleans of every mix, empty
    arrays, and the truth of numbers (NaN and -0.0 included)."""
    from extended_tracker.memo import all_of, any_of

    rng = np.random.default_rng(3)
    cases = [np.zeros(0, bool), np.zeros((3, 0), bool), np.array(True), np.array([0.0, -0.0]),
             np.array([np.nan, 1.0]), np.array([np.nan, 0.0]), np.array([0, 2, -1]),
             np.ones((2, 3), bool), np.eye(3, dtype=bool)]
    for n in (1, 2, 7, 60, 1000):
        for p in (0.0, 0.5, 0.99, 1.0):
            cases.append(rng.random(n) < p)
    for a in cases:
        assert all_of(a) == bool(a.all())
        assert any_of(a) == bool(a.any())
        if a.ndim == 1:
            assert all_of(a) == bool(np.logical_and.reduce(a))
            assert any_of(a) == bool(np.logical_or.reduce(a))


def test_take_by_row_index_gathers_what_fancy_indexing_gathers():
    """Mixture.take (and the other containers' take) gather the matrix fields by
    ``ndarray.take`` on memo.row_index: the same rows as indexing every field with
    ``idx``, for index arrays, lists, negative indices, boolean masks and slices; a mask
    of the wrong length is an IndexError as with indexing."""
    from extended_tracker.memo import row_index

    mix = _mixture()
    for idx in [np.array([2, 0]), [1], np.array([-1, 0, 0]), np.zeros(0, np.int64),
                np.array([True, False, True]), np.zeros(3, bool), slice(1, None),
                slice(None, None, -1)]:
        got = mix.take(idx)
        for f in dataclasses.fields(mix):
            want = getattr(mix, f.name)[idx]
            assert np.array_equal(getattr(got, f.name), want)
            assert getattr(got, f.name).dtype == want.dtype
        assert np.array_equal(np.arange(3)[row_index(idx, 3)], np.arange(3)[idx])
    est = Estimates.empty()
    assert len(est.take(np.zeros(0, bool))) == 0
    for bad in (np.array([True, False]), np.ones(4, bool)):
        with pytest.raises(IndexError):
            mix.take(bad)
