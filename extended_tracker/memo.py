"""
Read-only shared arrays, the memoising decorator of the filter's constant tables, a lean
``dataclasses.replace`` and ``__init__`` for the per-scan state objects, and cheaper
stand-ins for numpy calls a scan makes dozens of times on arrays of a few elements (0-d
constants, truth tests, row gathers), each held to what it replaces by the tests.

Kept apart from the GGIW module: the CPHD update, which takes no GGIW detail, uses it too.
"""

from __future__ import annotations

import dataclasses
from functools import lru_cache, wraps

import numpy as np


def read_only(*arrays):
    """The arrays, marked read-only: cached results shared by every caller."""
    for a in arrays:
        # setflags, not flags.writeable: the flags object built to set one flag cost
        # 1200 instructions of 2900, and a scan marks some seventeen arrays
        a.setflags(write=False)
    return arrays


def constants(*values):
    """
    The values as read-only 0-d float64 arrays, for the constants of hot array expressions.

    numpy 2 resolves the type of a Python scalar operand on every call, which costs about
    as much again as the arithmetic on arrays of a few dozen elements (``a * 0.5`` some
    850 ns where ``a * HALF`` takes 470, 3000 instructions against 1500); a 0-d float64
    array is an operand like any array, and the same doubles come out (for float64 and
    integer arrays: float32 ones would be promoted).
    """
    return read_only(*(np.array(float(x)) for x in values))


HALF, ONE, TWO, QUARTER, ZERO = constants(0.5, 1.0, 2.0, 0.25, 0.0)


def int_constants(*values):
    """The values as read-only 0-d int64 arrays: :func:`constants` for the operands of
    integer array expressions (counts, indices), whose results stay int64."""
    return read_only(*(np.array(int(x), dtype=np.int64) for x in values))


ZERO_I, ONE_I, TWO_I, FOUR_I = int_constants(0, 1, 2, 4)

try:
    # the C function np.count_nonzero calls without an axis, without its Python wrapper
    from numpy._core.multiarray import count_nonzero as _count_nonzero
except ImportError:                      # pragma: no cover - other numpy releases
    _count_nonzero = np.count_nonzero


def all_of(a: np.ndarray) -> bool:
    """
    Whether every element of the array ``a`` is true (``True`` when it is empty).

    For a 1-D ``a``, ``np.logical_and.reduce(a)``'s value (``a.all()``'s for any shape):
    a count of the nonzero elements takes about 1600 instructions where the reduction's
    set-up takes 7300 (or ``a.all()``'s 8000), on the dozens of arrays of a few elements a
    scan tests.
    """
    return _count_nonzero(a) == a.size


def row_index(idx, n: int) -> np.ndarray:
    """
    ``idx`` (an index array or list, a boolean mask over ``n`` rows, or a slice) as an
    index array, for ``a.take(rows, axis=0)``.

    Gathering rows of (n, 4, 4) arrays by ``take`` costs about 3300 instructions where
    fancy indexing costs 10 000 (12 000 with a boolean mask); the per-scan containers
    gather six to eight such fields at a time. A mask of another length than ``n`` is an
    IndexError, as fancy indexing with it would be.
    """
    if isinstance(idx, slice):
        return np.arange(n)[idx]
    idx = np.asarray(idx)
    if idx.dtype == bool:
        if idx.shape != (n,):
            raise IndexError(f'boolean index of shape {idx.shape} for {n} rows')
        return idx.nonzero()[0]
    return idx


def any_of(a: np.ndarray) -> bool:
    """Whether some element of the array ``a`` is true (``a.any()``'s value, counted as in
    :func:`all_of`)."""
    return _count_nonzero(a) > 0


def cached_tables(maxsize: int):
    """
    Memoise a function of a few hashable scalars (sizes, rates, a scan period) that
    returns an array or a tuple of arrays, keeping the ``maxsize`` most recent results.

    The results are shared by every caller, so they are returned read-only;
    ``.uncached`` is the plain function (fresh, writable arrays), for comparison.
    """
    def decorate(fn):
        @lru_cache(maxsize=maxsize)
        @wraps(fn)
        def cached(*args):
            out = fn(*args)
            return read_only(*out) if isinstance(out, tuple) else read_only(out)[0]
        cached.uncached = fn
        return cached
    return decorate


class cached_attribute:
    """
    ``functools.cached_property`` without its lock: computed on the first access and
    stored in the instance's ``__dict__``, where later accesses find it without this
    descriptor. Python 3.11's ``cached_property`` takes an ``RLock`` on every first access
    (3.12 dropped it), and a scan computes some seven such values. Two threads reading
    one new object at once might both compute it; they get the same value.
    """

    def __init__(self, func):
        self.func = func
        self.name = func.__name__
        self.__doc__ = func.__doc__

    def __set_name__(self, owner, name):
        self.name = name

    def __get__(self, obj, objtype=None):
        if obj is None:
            return self
        value = obj.__dict__[self.name] = self.func(obj)
        return value


def lean_init(cls):
    """
    Class decorator, above ``@dataclass(frozen=True)``: an ``__init__`` that stores the
    fields into the instance's ``__dict__`` (as :func:`evolve` does), for the per-scan
    state objects.

    The frozen dataclass ``__init__`` calls ``object.__setattr__`` once per field: some
    10 700 instructions to build a :class:`~extended_tracker.ggiw.Mixture` of eight
    fields, against 4300 this way, and a scan builds about a dozen such objects. The
    signature, the defaults and the frozen ``__setattr__`` are the dataclass's; only for
    a class whose ``__init__`` just stores its fields (no ``__post_init__``, ``InitVar``,
    ``init=False``, keyword-only field or default factory), which is checked here. The
    dataclass's own ``__init__`` stays as ``cls.__init__.dataclass_init``, for comparison.
    """
    fields = dataclasses.fields(cls)
    names = [f.name for f in fields]
    # fields() leaves out InitVar (and ClassVar) pseudo-fields: a count that differs
    if (hasattr(cls, '__post_init__') or 'self' in names or '_d' in names
            or any(not f.init or f.kw_only or f.default_factory is not dataclasses.MISSING
                   for f in fields)
            or len(names) != len(cls.__dataclass_fields__)):
        raise TypeError(f'lean_init: {cls.__name__}.__init__ does more than store fields')
    defaults = {f'_default_{f.name}': f.default for f in fields
                if f.default is not dataclasses.MISSING}
    params = ', '.join(n if f'_default_{n}' not in defaults else f'{n}=_default_{n}'
                       for n in names)
    body = ''.join(f'    _d[{n!r}] = {n}\n' for n in names)
    namespace = dict(defaults)
    exec(f'def __init__(self, {params}):\n    _d = self.__dict__\n{body}', namespace)
    init = namespace['__init__']
    init.__qualname__ = f'{cls.__qualname__}.__init__'
    init.__module__ = cls.__module__
    init.dataclass_init = cls.__init__
    cls.__init__ = init
    return cls


def evolve(obj, **changes):
    """
    ``dataclasses.replace(obj, **changes)`` for a frozen dataclass whose ``__init__`` only
    stores its fields (no ``__post_init__``, ``InitVar`` or ``init=False`` field), without
    replace's per-field Python loop: 0.7 against 2.4 us, and a scan makes several.

    Only the fields are copied, so cached properties of ``obj`` are not carried over.
    """
    cls = type(obj)
    fields = cls.__dataclass_fields__
    if not changes.keys() <= fields.keys():
        unknown = sorted(changes.keys() - fields.keys())
        raise TypeError(f'{cls.__name__} has no field {unknown[0]!r}')
    new = object.__new__(cls)
    d, src = new.__dict__, obj.__dict__
    for name in fields:
        d[name] = src[name]
    d.update(changes)
    return new
