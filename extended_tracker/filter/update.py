"""
The multi-object update of the GGIW-CPHD (or PHD) filter with one scan's detections.

It runs in two calls so that the sensor model stays outside the filter:

1. :func:`pair_updates` gates the predicted components, partitions the detections and
   updates every gated (component, cell) pair and one birth hypothesis per cell;
2. the caller evaluates what the sensor says about those updated pairs (their p_D where
   the cell puts them, which birth hypotheses it could not have seen);
3. :func:`update` weighs everything over the partitions (cardinality update), assembles
   the labelled posterior mixture and reduces it.

The model and its equations: ``doc/model.md``, sections 3-5.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..config import TrackerConfig
from ..diagnostics import Diagnostics
from .algebra2 import eig2, inv2
from .assemble import assemble, UpdateFacts
from .births import birth_intensity, birth_log_miss_factor, birth_prior
from .cardinality import add_cardinality, poisson_log_pmf, thin_cardinality
from .clutter import clutter_count, clutter_rate_in_use, learned_clutter_rate
from .cphd import cphd_update, phd_update, UpdateWeights
from .ggiw import (
    cell_stats, CellStats, gate_covariance, gate_pairs, log_miss_factor, PairUpdate, update_pairs,
)
from .hidden import held_p_d, out_of_sight
from .mixture import Mixture
from .partition import build_partitions, distinct_with_lonely, PartitionSet
from .reduction import reduce_mixture
from .state import FilterState
from .tables import cached_tables


@dataclass(frozen=True)
class SensorTerms:
    """
    What the detection model says about each predicted component (arrays of length n).

    Attributes
    ----------
    p_d : (n,) array
        Probability of detection.
    rate_scale : (n,) array or None
        Factor on the expected number of detections (the visible fraction).
    visibility : (n,) array or None
        Visible fraction, carried into the estimates.
    centroid_offset : (n, 2) array or None
        Expected offset of the visible part's centroid from the centre (m).
    shadowed : (n,) bool array or None
        Components whose own extent lies wholly in shadow (see :func:`hidden.held_p_d`).
    in_open : (n,) bool array or None
        Components with no background in front of them: their labels may coast on to
        ``reduction.max_open_position_std`` (:func:`implausible`).

    """

    p_d: np.ndarray
    rate_scale: np.ndarray | None = None
    visibility: np.ndarray | None = None
    centroid_offset: np.ndarray | None = None
    shadowed: np.ndarray | None = None
    in_open: np.ndarray | None = None

    @staticmethod
    def constant(n: int, p_d: float) -> 'SensorTerms':
        """The same p_D for every component, nothing else known."""
        return SensorTerms(np.full(n, float(p_d)))


@dataclass(frozen=True)
class Pairs:
    """
    What :func:`pair_updates` computed: the cells and every gated pair, updated.

    ``updated`` holds the ``k`` gated (component, cell) pairs first, then the birth
    hypothesis of every cell in cell order.
    """

    points: np.ndarray
    partitions: PartitionSet
    stats: CellStats
    comp: np.ndarray
    cell: np.ndarray
    updated: PairUpdate
    area: float
    rate_scale: np.ndarray | None = None    # the components' rate scale the update used

    @property
    def n_cells(self) -> int:
        return len(self.stats.n)

    def births(self, cells: np.ndarray) -> PairUpdate:
        """The birth hypotheses of ``cells``, each updated with its cell."""
        return self.updated.take(len(self.comp) + np.asarray(cells, dtype=np.int64))

    def free_birth_cells(self, pair_p_d: np.ndarray, min_points: int) -> np.ndarray:
        """
        The cells (indices) a birth may come from that no pair the sensor could have
        detected (``pair_p_d > 0``) explains: the only births a sensor's refusal
        (:func:`update`'s ``birth_unseen``) can change.
        """
        free = self.stats.n >= min_points
        free[self.cell[np.asarray(pair_p_d) > 0.0]] = False
        return free.nonzero()[0]

    @property
    def m(self) -> np.ndarray:
        """(k, 4) posterior means of the gated pairs."""
        return self.updated.m[:len(self.comp)]

    @property
    def P(self) -> np.ndarray:
        """(k, 4, 4) posterior covariances of the gated pairs."""
        return self.updated.P[:len(self.comp)]


def sensor_noise(cfg: TrackerConfig) -> np.ndarray:
    """Sensor noise covariance R (m^2), read-only."""
    return _noise(cfg.model.sigma_range)


@cached_tables(maxsize=8)
def _noise(sigma_range: float) -> np.ndarray:
    """``sigma_range^2 I``."""
    return sigma_range ** 2 * np.eye(2)


def gate_threshold(cfg: TrackerConfig) -> float:
    """Squared Mahalanobis gate of (component, cell) pairs (chi-square, 2 dof)."""
    p = cfg.partition.gate_probability
    if p >= 1.0:
        return float(np.inf)           # no gate (log1p(-1) would warn)
    return float(-2.0 * np.log1p(-p))


# the Poisson clutter cardinality pmf (log), asked for with the clutter rate and the
# scan's number of detections, which repeat
_clutter_log_pmf = cached_tables(maxsize=256)(poisson_log_pmf)


def gates(mix: Mixture, cfg: TrackerConfig, min_weight: float = 0.5):
    """
    Inverse gate covariances of every component (for :func:`ggiw.gate_pairs`) and the
    confident predictions for partitioning: centres, gates and rates of the heaviest
    component of each label of weight ``>= min_weight`` (None if there is none).
    """
    if not len(mix):
        return None, None
    R = sensor_noise(cfg)
    G = gate_covariance(mix, cfg.model.rho, R)
    order, is_head, _ = mix.by_label()
    best = order[is_head]
    best = best[mix.w[best] >= min_weight]
    if not len(best):
        return inv2(G), None
    # both sets of 2x2 matrices inverted in one batch
    n = len(mix)
    inverses = inv2(np.concatenate([G, mix.P[best][:, :2, :2] + mix.expected_extent(best) + R]))
    return inverses[:n], {
        'centre': mix.m[best][:, :2],
        'gate_inv': inverses[n:],
        'gate': gate_threshold(cfg),
        'rate': mix.expected_rate()[best],
    }


def pair_updates(mix: Mixture, points: np.ndarray, cfg: TrackerConfig, sensor: SensorTerms,
                 area: float | None = None,
                 clutter_log_density: np.ndarray | None = None) -> Pairs:
    """
    Gate, partition and update: every gated (component, cell) pair and every cell's
    birth hypothesis, in one batch.

    Parameters
    ----------
    mix : Mixture
        Predicted mixture (:func:`state.predict_state`).
    points : (m, 2) array
        Detections (m), finite.
    cfg : TrackerConfig
    sensor : SensorTerms
        The detection model of the predicted components.
    area : float, optional
        Area (m^2) births, and clutter unless ``clutter_log_density`` is given, are spread
        over; ``model.surveillance_area`` if omitted.
    clutter_log_density : (m,) array, optional
        ``log c(z)`` of each detection (1/m^2); uniform over ``area`` if omitted.

    Raises
    ------
    ValueError
        If a detection is not finite (the scan conversion never passes one).

    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if not np.isfinite(points).all():
        bad = int((~np.isfinite(points).all(axis=1)).sum())
        raise ValueError(f'pair_updates: detections must be finite; {bad} of '
                         f'{len(points)} rows are not')
    area = area if area else cfg.model.surveillance_area
    gate_inv, confident = gates(mix, cfg)
    pset = build_partitions(points, cfg.partition, confident)
    stats = cell_stats(points, pset.cells, clutter_log_density)
    R = sensor_noise(cfg)
    comp, cell = gate_pairs(mix, stats, cfg.model.rho, R, gate_threshold(cfg), gate_inv)
    n_cells = len(pset.cells)
    # the existing components and one birth row per cell, updated in one batch
    both = Mixture.concat([mix, birth_prior(stats, cfg, area)])
    rate_scale, hidden, offset = _per_component_terms(sensor)
    updated = update_pairs(both, np.concatenate([comp, len(mix) + np.arange(n_cells)]),
                           stats, np.concatenate([cell, np.arange(n_cells)]), cfg.model.rho,
                           R, _pad(rate_scale, n_cells, 1.0), _pad(hidden, n_cells, 0.0),
                           _pad(offset, n_cells, 0.0))
    return Pairs(points, pset, stats, comp, cell, updated, area, rate_scale)


def _per_component_terms(sensor: SensorTerms):
    """Rate scale (at least 1e-3), hidden fraction and centroid offset, or None."""
    rate_scale = hidden = None
    if sensor.rate_scale is not None:
        rate_scale = np.maximum(np.asarray(sensor.rate_scale, dtype=float), 1e-3)
    if sensor.visibility is not None:
        hidden = np.minimum(np.maximum(1.0 - sensor.visibility, 0.0), 1.0)
    return rate_scale, hidden, sensor.centroid_offset


def _pad(a, n: int, fill: float):
    """``a`` with ``n`` rows of ``fill`` appended (None stays None)."""
    if a is None:
        return None
    return np.concatenate([a, np.full((n,) + a.shape[1:], fill)])


@dataclass(frozen=True)
class _Kept:
    """The gated pairs with a p_D above zero: components, cells, p_D, log-likelihoods and
    their rows in ``Pairs.updated``."""

    comp: np.ndarray
    cell: np.ndarray
    p_d: np.ndarray
    log_lik: np.ndarray
    rows: np.ndarray


def _kept_pairs(pairs: Pairs, pair_p_d: np.ndarray) -> _Kept:
    """The pairs the sensor could have detected (``pair_p_d > 0``)."""
    keep = (np.asarray(pair_p_d) > 0.0).nonzero()[0]
    log_lik = pairs.updated.log_lik[:len(pairs.comp)]
    return _Kept(pairs.comp[keep], pairs.cell[keep], pair_p_d[keep], log_lik[keep], keep)


def update(pred: FilterState, pairs: Pairs, sensor: SensorTerms, pair_p_d: np.ndarray,
           cfg: TrackerConfig, dt: float, diag: Diagnostics,
           birth_unseen: np.ndarray | None = None,
           confirmed: np.ndarray | None = None,
           learn_clutter: bool = True) -> tuple[FilterState, UpdateFacts]:
    """
    The multi-object update: weigh the pairs over the partitions, assemble and reduce.

    Parameters
    ----------
    pred : FilterState
        The predicted state whose mixture :func:`pair_updates` was given.
    pairs : Pairs
    sensor : SensorTerms
    pair_p_d : (k,) array
        p_D of each gated pair where its cell puts the object (``sensor.p_d[pairs.comp]``
        when the sensor model says nothing more).
    cfg : TrackerConfig
    dt : float
        The prediction step (s): the birth intensity is ``birth.rate * dt``.
    diag : Diagnostics
        Filled with the update's counts.
    birth_unseen : (c,) bool array, optional
        Cells whose birth hypothesis is no object the sensor could see; refused where no
        existing component is paired with the cell (:meth:`Pairs.free_birth_cells`: only
        those need to be evaluated).
    confirmed : (r,) int array, optional
        Confirmed labels, ascending: with ``detection.hold_hidden``, those wholly in
        shadow are held from a miss (:func:`hidden.held_p_d`).
    learn_clutter : bool
        Whether this scan's clutter count teaches the learned clutter rate (not while the
        caller hides part of the scan from the filter: a background warm-up).

    Returns
    -------
    state : FilterState
        The reduced posterior (labels as the update left them).
    facts : UpdateFacts
        Detections and visibility of each label, for extraction.

    """
    diag.partitions = len(pairs.partitions.partitions)
    diag.cells = pairs.n_cells
    diag.capped_partitions = pairs.partitions.capped_partitions
    diag.capped_cells = pairs.partitions.capped_cells
    kept = _kept_pairs(pairs, np.asarray(pair_p_d, dtype=float))
    diag.pairs = len(kept.comp)
    p_d = np.asarray(sensor.p_d, dtype=float).reshape(len(pred.mixture))
    held = None
    if sensor.shadowed is not None and cfg.detection.hold_hidden:
        p_d, held = held_p_d(pred.mixture, confirmed, p_d, sensor.shadowed, kept.comp,
                             kept.cell, pairs.stats.mean, sensor_noise(cfg))
        diag.held = int(np.count_nonzero(held))
    log_g = _detection_log_likelihoods(pred.mixture, pairs, kept, cfg, birth_unseen, diag)
    lonely = _lonely_cells(pairs.stats.n, log_g, cfg, diag.sparse_births)
    weights = cardinality_update(pred, pairs, kept, log_g, p_d, pairs.rate_scale, held, lonely,
                                 clutter_rate_in_use(pred, cfg), cfg, dt)
    diag.unexplained = int(not weights.possible)
    posterior, next_label, facts = assemble(pred, pairs, kept, weights, sensor.visibility,
                                            cfg, diag)
    in_open = None if sensor.in_open is None else pred.mixture.label[sensor.in_open]
    reduced = reduce(posterior, cfg, diag, in_open)
    learned = pred.clutter_rate
    if weights.possible and learn_clutter:
        count = clutter_count(weights, pairs.stats.n, len(pairs.points))
        learned = learned_clutter_rate(learned, count, dt, cfg)
    return FilterState(reduced, weights.log_card, next_label, learned), facts


def _lonely_cells(cell_size: np.ndarray, log_g: np.ndarray, cfg: TrackerConfig,
                  refused_births: int):
    """
    Cells of several returns that no object and no birth explains (None if there are
    none): the update takes them as clutter return by return, since clutter alone would
    make every partition holding them impossible, and the cardinality NaN from then on.
    Only births can leave such cells: with ``birth.min_points`` above 2, or births
    refused.
    """
    if not (cfg.birth.min_points > 2 or refused_births):
        return None
    lonely = (cell_size > 1) & ~np.isfinite(log_g).any(axis=0)
    return lonely if lonely.any() else None


def _detection_log_likelihoods(mix: Mixture, pairs: Pairs, kept: _Kept, cfg: TrackerConfig,
                               birth_unseen, diag: Diagnostics) -> np.ndarray:
    """
    ``log g`` (n + 1, c): ``log p_D + log l`` of each kept pair and, in the last row, of
    each cell's birth; ``-inf`` elsewhere.

    A birth needs ``birth.min_points`` returns; one the sensor could not have seen
    (``birth_unseen``) on a cell no component is paired with is refused: beside a track a
    few returns are as likely its own (a walker's leg).
    """
    n_comp, stats = len(mix), pairs.stats
    log_g = np.full((n_comp + 1, pairs.n_cells), -np.inf)
    log_g[kept.comp, kept.cell] = np.log(kept.p_d) + kept.log_lik
    born_ok = stats.n >= cfg.birth.min_points
    if birth_unseen is not None:
        free = born_ok.copy()
        free[kept.cell] = False
        refused = free & birth_unseen
        diag.sparse_births = int(np.count_nonzero(refused))
        born_ok &= ~refused
    birth_lik = pairs.updated.log_lik[len(pairs.comp):]
    log_g[n_comp, :] = np.where(born_ok, np.log(cfg.detection.p_d0) + birth_lik, -np.inf)
    return log_g


def cardinality_update(pred: FilterState, pairs: Pairs, kept: _Kept, log_g: np.ndarray,
                       p_d: np.ndarray, rate_scale, held, lonely, clutter_rate: float,
                       cfg: TrackerConfig, dt: float) -> UpdateWeights:
    """
    Weigh every pair over the partitions (CPHD, or PHD in ``model.mode`` ``phd``).

    The components are the predicted mixture plus one row for the uniform birth
    intensity (weight ``birth.rate * dt``). Partitions that the ``lonely`` cells make
    twins of each other count once (:func:`partition.distinct_with_lonely`). In CPHD
    mode, one object's worth of each ``held`` label wholly out of sight is kept out of
    the update (:func:`hidden.out_of_sight`).
    """
    mc, mix, stats = cfg.model, pred.mixture, pairs.stats
    partitions = pairs.partitions.partitions
    if lonely is not None:
        partitions = distinct_with_lonely(partitions, pairs.partitions.cells, stats.n,
                                          lonely, len(pairs.points))
    with np.errstate(divide='ignore'):
        log_w = np.concatenate([np.log(mix.w), [np.log(birth_intensity(cfg, dt))]])
    log_qd = np.concatenate([log_miss_factor(mix, p_d, rate_scale),
                             [birth_log_miss_factor(cfg)]])
    cell_log_c = -stats.n * np.log(pairs.area) if stats.log_c is None else stats.log_c
    if mc.mode != 'cphd':
        return phd_update(log_w, log_qd, log_g, cell_log_c, stats.n, partitions,
                          clutter_rate, mc.n_max, lonely)
    # the clutter pmf up to every detection: no partition can take more as clutter
    clutter_pmf = _clutter_log_pmf(clutter_rate, len(pairs.points) + 1)
    apart = None if held is None else out_of_sight(mix, held, kept.comp)
    if apart is None:
        return cphd_update(log_w, log_qd, log_g, cell_log_c, stats.n, partitions,
                           pred.log_card, clutter_pmf, lonely)
    # labels wholly out of sight: one object's worth of each kept out of the update
    rows, w_apart = apart
    total_apart = float(np.sum(w_apart))
    with np.errstate(divide='ignore'):
        log_w[rows] = np.log(np.maximum(mix.w[rows] - w_apart, 0.0))
    out = cphd_update(log_w, log_qd, log_g, cell_log_c, stats.n, partitions,
                      thin_cardinality(pred.log_card, total_apart), clutter_pmf, lonely)
    log_w_missed = out.log_w_missed.copy()
    log_w_missed[rows] = np.log(np.exp(log_w_missed[rows]) + w_apart)
    return UpdateWeights(log_w_missed, out.log_w_detected,
                         add_cardinality(out.log_card, total_apart),
                         out.log_partition_weight, out.possible)


def reduce(posterior: Mixture, cfg: TrackerConfig, diag: Diagnostics,
           in_open: np.ndarray | None = None) -> Mixture:
    """Drop implausible components (``in_open``: see :func:`implausible`), then prune,
    merge and cap (:func:`reduce_mixture`)."""
    oversized = implausible(posterior, cfg, in_open)
    diag.oversized = int(np.count_nonzero(oversized))
    if diag.oversized:
        posterior = posterior.take(~oversized)
    reduced, diag.capped_components = reduce_mixture(
        posterior, cfg.reduction.prune_weight, cfg.reduction.merge_distance,
        cfg.reduction.max_components)
    return reduced


def implausible(mix: Mixture, cfg: TrackerConfig, in_open: np.ndarray | None = None
                ) -> np.ndarray:
    """
    Components to drop: larger than any object tracked here (walls, clutter lines), or
    coasted until their position is unknown within metres (they could only claim
    far-away returns): a position std past ``max_position_std``, or past
    ``max_open_position_std`` for the labels ``in_open`` (no background in front of them,
    :class:`SensorTerms`).
    """
    red = cfg.reduction
    limit = np.full(len(mix), red.max_position_std)
    if in_open is not None and len(in_open):
        limit[np.isin(mix.label, in_open)] = red.max_open_position_std
    pos_var = np.maximum(mix.P[:, 0, 0], mix.P[:, 1, 1])
    coasted = pos_var > limit ** 2
    if not len(mix):
        return coasted
    major2, _ = eig2(mix.expected_extent())
    return (major2 > cfg.reduction.max_semi_axis ** 2) | coasted
