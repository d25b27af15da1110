"""
Gamma Gaussian inverse Wishart (GGIW) components: prediction and single-cell update.

A mixture is a struct of arrays with a leading component axis. Conventions follow
``doc/model.md`` (Koch's inverse Wishart, ``d = 2``, ``E[X] = V / (v - 2d - 2)``).

Notes
-----
The update is the decoupled random-matrix update of Feldmann et al. / Granström et al.
(IEEE TAES 56(1), 2020), with the measurement spread ``rho X + R``. The predicted
likelihood contains the Gamma-Poisson term ``E[exp(-gamma) gamma^n]``.

"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import gammaln

from .algebra2 import inv2, logdet_spd2, quad_form2_xy, sqrtm_spd2, symmetrize
from .mixture import D, IW_OFFSET, Mixture
from .tables import cached_tables

# log Gamma_2 (scipy.special.multigammaln(a, 2), which the reference test evaluates) is
# written out in update_pairs
_HALF_LOG_PI = 0.5 * np.log(np.pi)


_LOG_PI = 2.0 * _HALF_LOG_PI


@cached_tables(maxsize=256)        # scan periods jitter in recordings
def cv_matrices(dt: float, sigma_accel: float):
    """
    Constant-velocity transition ``F`` and process noise ``Q`` for a step of ``dt`` s
    (cached per step and noise, read-only).

    Notes
    -----
    Piecewise-constant white acceleration: ``Q = sigma_a^2 G G^T``,
    ``G = [dt^2/2 I; dt I]``, one random acceleration of std ``sigma_a`` held over each
    step. Its velocity variance per second, ``sigma_a^2 dt``, follows the scan period:
    ``sigma_a`` 2 gives 0.4 m^2/s^3 at 10 Hz and 0.09 at 45 Hz, so a track coasts with a
    spread that depends on the scanner's rate (the forgetting does not: trap 3). The
    continuous form, ``q [[dt^3/3, dt^2/2], [dt^2/2, dt]]`` per axis, is the same at every
    rate; measured with q 0.1 it kept more of ``crowd20``'s hidden
    walkers but on positive_1 held a 3.5 m/s track behind the background for 22 scans,
    and it is not in.

    """
    F = np.eye(4)
    F[0, 2] = F[1, 3] = dt
    g = np.array([0.5 * dt * dt, 0.5 * dt * dt, dt, dt])
    Q = np.zeros((4, 4))
    for i, j in ((0, 0), (1, 1), (2, 2), (3, 3), (0, 2), (2, 0), (1, 3), (3, 1)):
        Q[i, j] = g[i] * g[j]
    return F, sigma_accel ** 2 * Q


FORGET_FLOOR = 1e-9      # least Gamma shape, and IW v - 6, that forgetting leaves


def _forgetting(dt: float, tau: float) -> float:
    """``exp(-dt / tau)``, the factor a step of ``dt`` s keeps of a time constant ``tau``."""
    return np.exp(-dt / tau)


def predict(mix: Mixture, dt: float, p_survival: float, sigma_accel: float, tau_rate: float,
            tau_extent: float) -> Mixture:
    """
    Predict every component ``dt`` seconds ahead.

    Parameters
    ----------
    mix : Mixture
        Posterior mixture of the previous scan.
    dt : float
        Step in seconds, ``>= 0``.
    p_survival : float
        Survival probability per second; the step uses ``p_survival ** dt``.
    sigma_accel, tau_rate, tau_extent : float
        CV noise (m/s^2) and the forgetting time constants (s).

    Notes
    -----
    ``alpha+ = alpha e^{-dt/tau_r}``, ``beta+ = beta e^{-dt/tau_r}`` (mean kept);
    ``v+ = 6 + e^{-dt/tau_X} (v - 6)``, ``V+ = (v+ - 6)/(v - 6) V`` (mean kept). Forgetting
    is per second, not per scan (trap 3), and V is rescaled with v (trap 4). What it
    leaves of ``alpha`` and of ``v - 6`` is held at ``FORGET_FLOOR`` at least (means kept):
    with a time constant far below the scan period, or a track coasting for long, it
    would underflow to 0, and the rate and extent to 0/0.

    """
    if dt < 0:
        raise ValueError(f'dt must be >= 0, got {dt}')
    if not len(mix):
        return mix
    F, Q = cv_matrices(dt, sigma_accel)
    m = mix.m @ F.T
    P = symmetrize(F @ mix.P @ F.T + Q)
    k_rate = _forgetting(dt, tau_rate)
    k_ext = _forgetting(dt, tau_extent)
    alpha, beta = mix.alpha * k_rate, mix.beta * k_rate
    if np.min(alpha) < FORGET_FLOOR:
        low = alpha < FORGET_FLOOR
        beta = np.where(low, FORGET_FLOOR * (mix.beta / mix.alpha), beta)
        alpha = np.where(low, FORGET_FLOOR, alpha)
    s = mix.v - IW_OFFSET
    v_new = IW_OFFSET + k_ext * s
    if np.min(v_new) < IW_OFFSET + FORGET_FLOOR:
        v_new = np.maximum(v_new, IW_OFFSET + FORGET_FLOOR)
    V_new = mix.V * ((v_new - IW_OFFSET) / s)[:, None, None]
    return Mixture(mix.w * p_survival ** dt, alpha, beta, m, P, v_new, V_new, mix.label)


@dataclass(frozen=True)
class CellStats:
    """
    Sufficient statistics of cells.

    Attributes
    ----------
    n : (c,) int array
        Number of detections in each cell.
    mean : (c, 2) array
        Centroid ``z_bar``.
    scatter : (c, 2, 2) array
        ``Z = sum (z - z_bar)(z - z_bar)^T``.
    log_c : (c,) array or None
        ``log c^W``, the sum of the detections' log clutter densities, when
        :func:`cell_stats` is given them.

    """

    n: np.ndarray
    mean: np.ndarray
    scatter: np.ndarray
    log_c: np.ndarray | None = None


def cell_stats(points: np.ndarray, cells: list[np.ndarray],
               log_density: np.ndarray | None = None) -> CellStats:
    """
    Return the centroid and scatter of each cell (a list of index arrays into points), and
    with ``log_density`` (m,), the log clutter density at each point, each cell's sum of
    it (``log c^W``).
    """
    c = len(cells)
    if c == 0:
        return CellStats(np.zeros(0, dtype=int), np.zeros((0, 2)), np.zeros((0, 2, 2)),
                         None if log_density is None else np.zeros(0))
    sizes = np.fromiter(map(len, cells), dtype=np.int64, count=c)
    flat = np.concatenate(cells)
    owner = np.arange(c).repeat(sizes)         # the method: np.repeat's wrapper costs more
    # the members' rows by take, the coordinates as views of them (indexing a column
    # with an index array costs three times as much)
    rows = points[flat]
    x, y = rows[:, 0], rows[:, 1]
    # per-cell sums by bincount: the same sequential sums as np.add.at, without its cost
    mx = np.bincount(owner, weights=x, minlength=c) / sizes
    my = np.bincount(owner, weights=y, minlength=c) / sizes
    mean = np.empty((c, 2))
    mean[:, 0] = mx
    mean[:, 1] = my
    dx, dy = x - mx[owner], y - my[owner]
    scatter = np.empty((c, 2, 2))
    scatter[:, 0, 0] = np.bincount(owner, weights=dx * dx, minlength=c)
    scatter[:, 0, 1] = scatter[:, 1, 0] = np.bincount(owner, weights=dx * dy, minlength=c)
    scatter[:, 1, 1] = np.bincount(owner, weights=dy * dy, minlength=c)
    log_c = (None if log_density is None
             else np.bincount(owner, weights=log_density[flat], minlength=c))
    return CellStats(sizes, mean, scatter, log_c)


@dataclass(frozen=True)
class PairUpdate:
    """Posterior GGIW parameters and predicted log-likelihoods of (component, cell) pairs."""

    log_lik: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    m: np.ndarray
    P: np.ndarray
    v: np.ndarray
    V: np.ndarray

    def take(self, idx) -> 'PairUpdate':
        """The pairs at ``idx`` (index array, slice or boolean mask)."""
        return PairUpdate(self.log_lik[idx], self.alpha[idx], self.beta[idx],
                          self.m[idx], self.P[idx], self.v[idx],
                          self.V[idx])

    def mixture(self, w, label) -> Mixture:
        """The updated components as a mixture with weights ``w`` and labels ``label``."""
        return Mixture(w, self.alpha, self.beta, self.m, self.P, self.v, self.V, label)


def update_pairs(mix: Mixture, comp: np.ndarray, stats: CellStats, cell: np.ndarray,
                 rho: float, R: np.ndarray, rate_scale: np.ndarray | None = None,
                 hidden: np.ndarray | None = None,
                 centroid_offset: np.ndarray | None = None) -> PairUpdate:
    """
    Update components ``comp[k]`` with cells ``cell[k]``; all pairs in one batch.

    Parameters
    ----------
    mix : Mixture
        Predicted mixture.
    comp, cell : (k,) int arrays
        The pairs to update.
    stats : CellStats
        Statistics of all cells.
    rho : float
        Extent scale of the measurement spread.
    R : (2, 2) array
        Sensor noise covariance.
    rate_scale : (n,) array, optional
        Factor ``f`` on the measurement rate of each component in this scan (the visible
        fraction): ``gamma_eff = f gamma``, so the Gamma rate seen is ``beta / f`` and the
        posterior rate is ``beta + f``.
    hidden : (n,) array, optional
        Hidden fraction ``h`` of each component in this scan. The centroid of the visible
        part of a partly hidden object is off its centre by up to ``h`` times its extent, so
        the centroid is treated as a noisier measurement: ``S += h^2 X`` (in the gain and
        the likelihood alike). Without it, an object covered from one side drifts away from
        its shadow and is lost.
    centroid_offset : (n, 2) array, optional
        Expected offset of the visible part's centroid from the centre (m): the innovation
        is ``z_bar - (H m + offset)``. Zero for a fully visible object.

    Returns
    -------
    PairUpdate
        ``log_lik[k] = log l_W`` of section 3 and the updated parameters.

    Notes
    -----
    ``S = H P H^T + Y/n`` with ``Y = rho X + R``, ``X = V / (v - 6)``;
    ``N = X^{1/2} S^{-1/2} e e^T S^{-T/2} X^{T/2}``,
    ``Zh = X^{1/2} Y^{-1/2} Z Y^{-T/2} X^{T/2}``; ``v' = v + n``, ``V' = V + N + Zh``;
    ``alpha' = alpha + n``, ``beta' = beta + 1``. The log-likelihood is written term by term
    in the code.

    """
    if not len(comp):
        # a scan without returns (the background's warm-up, an empty scene)
        return PairUpdate(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros((0, 4)),
                          np.zeros((0, 4, 4)), np.zeros(0), np.zeros((0, 2, 2)))
    n = stats.n[cell].astype(float)
    zbar = stats.mean[cell]
    Z = stats.scatter[cell]
    alpha = mix.alpha[comp]
    beta = mix.beta[comp]
    f = 1.0 if rate_scale is None else rate_scale[comp]
    m = mix.m[comp]
    P = mix.P[comp]
    v = mix.v[comp]
    V = mix.V[comp]

    X = V / (v - IW_OFFSET)[:, None, None]
    Y = rho * X + R
    Ppos = P[:, :2, :2]
    S = Ppos + Y / n[:, None, None]
    if hidden is not None:
        h = hidden[comp]
        S = S + (h * h)[:, None, None] * X
    # the 2x2 closed forms batched over every pair and every matrix they are needed of
    k = len(n)
    roots = sqrtm_spd2(np.concatenate([X, S, Y]))                  # X^1/2, S^1/2, Y^1/2
    X_half = roots[:k]
    inverses = inv2(np.concatenate([S, roots[k:]]))                # S^-1, S^-1/2, Y^-1/2
    S_inv, S_ihalf, Y_ihalf = inverses[:k], inverses[k:2 * k], inverses[2 * k:]
    PHt = P[:, :, :2]                                  # P H^T, (k, 4, 2)
    K = PHt @ S_inv                                    # (k, 4, 2)
    eps = zbar - m[:, :2]
    if centroid_offset is not None:
        eps = eps - centroid_offset[comp]
    m_new = m + np.einsum('kij,kj->ki', K, eps)
    P_new = symmetrize(P - K @ PHt.swapaxes(1, 2))          # K S K^T = K (P H^T)^T

    u = np.einsum('kij,kj->ki', X_half, np.einsum('kij,kj->ki', S_ihalf, eps))
    N_hat = u[:, :, None] * u[:, None, :]
    M = X_half @ Y_ihalf
    Z_hat = M @ Z @ M.swapaxes(1, 2)
    v_new = v + n
    V_new = symmetrize(V + N_hat + Z_hat)

    beta_eff = beta if rate_scale is None else beta / f      # f = 1: beta as it is
    log_lik = _pair_log_likelihood(n, alpha, beta_eff, v, v_new, logdet_spd2(
        np.concatenate([V, V_new, X, Y, S])).reshape(5, k))
    return PairUpdate(log_lik, alpha + n, beta + f, m_new, P_new, v_new, V_new)


def _pair_log_likelihood(n, alpha, beta_eff, v, v_new, logdets):
    """``log l_W`` of section 3 of ``doc/model.md``, term by term, for each pair;
    ``logdets`` holds the log-determinants of ``V, V', X, Y, S`` row by row."""
    alpha_new = alpha + n
    logdet_V, logdet_Vn, logdet_X, logdet_Y, logdet_S = logdets
    h0, h1 = 0.5 * (v - (D + 1)), 0.5 * (v_new - (D + 1))
    # log Gamma_2(a) = (1/2) log pi + log Gamma(a) + log Gamma(a - 1/2)
    lg2_new = _HALF_LOG_PI + gammaln(h1) + gammaln(h1 - 0.5)
    lg2_old = _HALF_LOG_PI + gammaln(h0) + gammaln(h0 - 0.5)
    return (
        # Gamma-Poisson: E[e^{-gamma} gamma^n] under Gam(alpha, beta_eff)
        gammaln(alpha_new) - gammaln(alpha) + alpha * np.log(beta_eff)
        - alpha_new * np.log(beta_eff + 1.0)
        # Gaussian normalisation of n points and of the centroid
        - n * _LOG_PI - np.log(n)                                   # d = 2
        # inverse Wishart normalisers before and after
        + h0 * logdet_V - h1 * logdet_Vn
        + lg2_new - lg2_old
        # centroid innovation and spread scaling
        + 0.5 * logdet_X - 0.5 * logdet_S + 0.5 * (n - 1.0) * (logdet_X - logdet_Y)
    )


def gate_covariance(mix: Mixture, rho: float, R: np.ndarray) -> np.ndarray:
    """``H P H^T + (1 + rho) X + R`` of every component: the gate of :func:`gate_pairs`."""
    return mix.P[:, :2, :2] + (1.0 + rho) * mix.expected_extent() + R


def log_miss_factor(mix: Mixture, p_d: np.ndarray, rate_scale: np.ndarray | None = None):
    """
    Return ``log q_D = log(1 - p_D + p_D (beta_eff / (beta_eff + 1))^alpha)`` per component.

    Notes
    -----
    A detected object still yields no point with probability ``E[e^{-gamma}]``; forgetting
    that term is trap 5.

    """
    beta_eff = mix.beta if rate_scale is None else mix.beta / rate_scale
    log_e0 = mix.alpha * (np.log(beta_eff) - np.log1p(beta_eff))
    # 1 - p_D (1 - e0), with 1 - e0 = -expm1(log e0) computed without cancellation
    return np.log1p(p_d * np.expm1(log_e0))


def gate_pairs(mix: Mixture, stats: CellStats, rho: float, R: np.ndarray, threshold: float,
               gate_inv: np.ndarray | None = None):
    """
    Return ``(comp, cell)`` index arrays of the pairs inside the gate.

    ``gate_inv`` (n, 2, 2), if given, is the inverse of :func:`gate_covariance`, computed by
    the caller along with other inverses.

    Notes
    -----
    The centroid of a cell is compared with the predicted position under the covariance of
    one detection, ``H P H^T + rho X + R``, widened by the full extent ``X`` so that a cell
    at an object's edge is kept: ``d^2 = e^T (HPH^T + (1 + rho) X + R)^{-1} e < threshold``.

    """
    nc, ncell = len(mix), len(stats.n)
    if nc == 0 or ncell == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    Gi = inv2(gate_covariance(mix, rho, R)) if gate_inv is None else gate_inv
    comp, cell = (gate_distance2(mix, stats.mean, Gi) < threshold).nonzero()
    return comp.astype(np.int64), cell.astype(np.int64)


def gate_distance2(mix: Mixture, z: np.ndarray, gate_inv: np.ndarray) -> np.ndarray:
    """(n, k) squared gate distance of each of the points ``z`` (k, 2) from each component's
    predicted position, ``gate_inv`` the inverse of :func:`gate_covariance`."""
    return centre_distance2(mix.m, gate_inv, z)


def centre_distance2(centre: np.ndarray, metric: np.ndarray, z: np.ndarray) -> np.ndarray:
    """
    (n, k) squared distance of each of the points ``z`` (k, 2) from each of the ``centre``
    rows (n, >= 2; the first two columns are the position), each in its own ``metric``
    (n, 2, 2, symmetric): gating here and partitioning's distances to the predictions.
    """
    # on (n, k) arrays of the coordinates and (n, 1) columns of the matrices rather than
    # broadcast views of (n, k, 2) and (n, 1, 2, 2)
    g = metric
    return quad_form2_xy(z[:, 0] - centre[:, :1], z[:, 1] - centre[:, 1:2],
                         g[:, :1, 0], g[:, :1, 1], g[:, 1:, 1])
