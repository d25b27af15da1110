"""
Another CPU, as far as float64 results go: numpy picks its vectorised kernels for
``exp``, ``log``, ``arctan2`` and the others by CPU (Intel's SVML on AVX-512, its own
or the C library's elsewhere), and they differ in the last bit.
"""

import numpy as np

FUNCTIONS = ('exp', 'log', 'log1p', 'expm1', 'arctan2', 'arcsin', 'hypot', 'sin', 'cos',
             'log2')


class LastBitNoise:
    """
    A numpy function whose float64 results move by one unit in the last place, up or
    down, for about a third of its inputs: what another CPU's vectorised kernels do
    (numpy picks them by CPU). Like any kernel it is a function: which inputs move, and
    which way, is decided by a hash of the inputs' bits, so equal inputs still give equal
    results. Exact values (0, +-1) stay exact, as every library keeps them.
    """

    def __init__(self, func, salt):
        self._func, self._salt = func, np.uint64(salt)

    def __getattr__(self, name):                 # ufunc methods (.at, .reduce) unchanged
        return getattr(self._func, name)

    def __call__(self, *args, **kwargs):
        out = self._func(*args, **kwargs)
        if not (isinstance(out, np.ndarray) and out.dtype == np.float64 and out.size):
            return out
        h = np.full(out.shape, self._salt, dtype=np.uint64)
        for a in args[:2]:
            bits = np.broadcast_to(np.asarray(a, dtype=np.float64), out.shape).view(np.uint64)
            with np.errstate(over='ignore'):
                h = (h ^ bits) * np.uint64(0x9E3779B97F4A7C15)
        h >>= np.uint64(56)                               # the top 8 bits: 0 .. 255
        move = (h < 85) & np.isfinite(out) & (out != 0) & (np.abs(out) != 1)
        away = np.where(h % np.uint64(2) == 0, np.inf, -np.inf)
        out[...] = np.where(move, np.nextafter(out, away), out)
        return out


def assert_same_tracks(plain, other, atol, least):
    """Two runs' per-scan ``(labels, means)``: the same ids in every scan, the means within
    ``atol``; ``plain`` holds at least ``least`` reports (the comparison has substance)."""
    assert sum(len(labels) for labels, _ in plain) >= least
    assert len(plain) == len(other)
    for (la, ma), (lb, mb) in zip(plain, other):
        assert list(la) == list(lb)
        np.testing.assert_allclose(ma, mb, rtol=0, atol=atol)


def other_cpu(monkeypatch, salt=0):
    """Replace the numpy functions of ``FUNCTIONS`` by :class:`LastBitNoise` ones."""
    for k, name in enumerate(FUNCTIONS):
        monkeypatch.setattr(np, name, LastBitNoise(getattr(np, name), salt + k))
