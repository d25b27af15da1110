"""
Closed-form algebra of symmetric 2x2 matrices, batched over leading axes: determinant,
inverse, eigenvalues, log-determinant, square root and quadratic forms.
"""

from __future__ import annotations

import numpy as np


def det2(A):
    """Determinant of (..., 2, 2) matrices."""
    return A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]


def inv2(A):
    """Inverse of (..., 2, 2) matrices."""
    out = np.empty_like(A)
    a, b, c, d = A[..., 0, 0], A[..., 0, 1], A[..., 1, 0], A[..., 1, 1]
    det = a * d - b * c                # det2 inlined: inv2 runs about ten times a scan
    # the adjugate, then one division by det: d / det, a / det, -b / det, -c / det
    out[..., 0, 0] = d
    out[..., 1, 1] = a
    np.negative(b, out=out[..., 0, 1])
    np.negative(c, out=out[..., 1, 0])
    out /= det[..., None, None]
    return out


def eig2(A):
    """
    Eigenvalues ``(largest, smallest)`` of symmetric (..., 2, 2) matrices, closed form:
    ``tr/2 +- sqrt((a - c)^2 / 4 + b^2)``.
    """
    a, b, c = A[..., 0, 0], A[..., 0, 1], A[..., 1, 1]
    half_tr = 0.5 * (a + c)
    d = a - c                                  # squared as d * d: d ** 2's values, no
    root = np.sqrt(0.25 * (d * d) + b * b)  # Python operand; a sum of squares, >= 0
    return half_tr + root, half_tr - root


def logdet_spd2(A):
    """
    Log-determinant of SPD (..., 2, 2) matrices through their Cholesky factor.

    ``log|A| = 2 log L00 + 2 log L11`` with ``L00 = sqrt(a)``, ``L11^2 = c - b^2 / a``: no
    cancellation beyond that of the Schur complement itself.
    """
    a = A[..., 0, 0]
    b = 0.5 * (A[..., 0, 1] + A[..., 1, 0])
    schur = A[..., 1, 1] - b * b / a
    return np.log(a) + np.log(schur)


def sqrtm_spd2(A):
    """
    Symmetric square root of SPD (..., 2, 2) matrices.

    Notes
    -----
    For 2x2 SPD ``A``: ``sqrt(A) = (A + s I) / t`` with ``s = sqrt(det A)`` and
    ``t = sqrt(tr A + 2 s)`` (Cayley-Hamilton). Symmetric roots keep the update rotation
    equivariant, which Cholesky roots do not.

    """
    s = np.sqrt(det2(A))
    t = np.sqrt(A[..., 0, 0] + A[..., 1, 1] + 2.0 * s)
    out = A.copy()
    out[..., 0, 0] += s
    out[..., 1, 1] += s
    return out / t[..., None, None]


def quad_form2(e, A):
    """
    ``e^T A e`` of (..., 2) vectors and symmetric (..., 2, 2) matrices, broadcast against
    each other, in closed form (the off-diagonal read once and doubled).
    """
    return quad_form2_xy(e[..., 0], e[..., 1], A[..., 0, 0], A[..., 0, 1], A[..., 1, 1])


def quad_form2_xy(x, y, a, b, c):
    """
    ``[x y] [[a b] [b c]] [x y]^T`` from the coordinates and the matrix entries, broadcast
    against each other: :func:`quad_form2` on arrays the caller lays out (contiguous
    coordinate arrays broadcast faster than views of stacked vectors and matrices).
    """
    return a * (x * x) + 2.0 * b * x * y + c * (y * y)


def symmetrize(A):
    """Return ``(A + A^T) / 2`` over the last two axes."""
    return 0.5 * (A + A.swapaxes(-1, -2))
