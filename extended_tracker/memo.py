"""
Read-only shared arrays and the memoising decorator of the filter's constant tables.

Kept apart from the GGIW module: the CPHD update, which takes no GGIW detail, uses it too.
"""

from __future__ import annotations

from functools import lru_cache, wraps


def read_only(*arrays):
    """The arrays, marked read-only: cached results shared by every caller."""
    for a in arrays:
        a.flags.writeable = False
    return arrays


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
