"""
Memoised constant tables: the filter's lookup arrays that depend only on a few scalars.

A scan asks for the same tables (factorials, the CV matrices of a scan period, a Poisson
pmf) again and again; they are computed once per argument set and shared, so they are
returned read-only.
"""

from __future__ import annotations

from functools import lru_cache, wraps


def read_only(*arrays):
    """The arrays, marked read-only (results shared by every caller)."""
    for a in arrays:
        a.flags.writeable = False
    return arrays


def cached_tables(maxsize: int):
    """
    Memoise a function of a few hashable scalars that returns an array or a tuple of
    arrays, keeping the ``maxsize`` most recent results, read-only.

    ``.uncached`` is the plain function (fresh, writable arrays), for tests.
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
