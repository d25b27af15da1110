"""
One filter step of the GGIW-CPHD (or PHD) tracker on Cartesian detections.

The state is data (:class:`FilterState`), passed in and returned. The laser front end and
the per-scan pipeline (:mod:`extended_tracker.pipeline`) call :func:`predict_state` and
:func:`update_state`; synthetic tests may call :func:`filter_step` directly.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import numpy as np


from .config import ExtractionConfig, TrackerConfig
from .cphd import (
    cphd_update, phd_update, poisson_log_pmf, predict_cardinality, resize_cardinality,
    thin_cardinality,
)
from .ggiw import (
    cell_stats, eig2, einsum, gate_covariance, gate_pairs, group_heads, inv2, IW_OFFSET,
    log_miss_factor, Mixture, predict, update_pairs, weight_key,
)
from .memo import cached_tables, evolve, read_only
from .partition import build_partitions, find_root, union_min
from .reduction import join_parts, reduce_mixture

NEG_INF = -np.inf
NO_LABELS = read_only(np.zeros(0, np.int64))[0]
# a thin contour piece (see group_segments): semi-minor axis at most this, semi-major at least
SEGMENT_MAX_SEMI_MINOR = 0.15        # m
SEGMENT_MIN_SEMI_MAJOR = 0.5         # m


@dataclass(frozen=True)
class Estimates:
    """
    Reported objects of one scan, arrays with a leading object axis of length ``k``.

    Attributes
    ----------
    label : (k,) int64
    existence : (k,) weight of the label, clipped to [0, 1]
    m : (k, 4) kinematic mean; P : (k, 4, 4) its covariance
    X : (k, 2, 2) expected extent matrix (m^2)
    rate : (k,) expected detections per scan
    num_detections : (k,) detections that updated the label this scan
    visibility : (k,) visible fraction used for p_D (1 where not computed)

    """

    label: np.ndarray
    existence: np.ndarray
    m: np.ndarray
    P: np.ndarray
    X: np.ndarray
    rate: np.ndarray
    num_detections: np.ndarray
    visibility: np.ndarray

    def __len__(self):
        return int(self.label.shape[0])

    def take(self, idx) -> 'Estimates':
        """The objects at ``idx`` (index array or boolean mask)."""
        return Estimates(self.label[idx], self.existence[idx], self.m[idx], self.P[idx],
                         self.X[idx], self.rate[idx], self.num_detections[idx],
                         self.visibility[idx])

    def axes(self):
        """Semi-major, semi-minor (m) and yaw of the major axis (rad) of each extent."""
        return self._axes

    @cached_property
    def _axes(self):
        # computed once per scan's estimates, read by messages, markers, shapes and plots
        # (shared, so read-only)
        lam1, lam2 = eig2(self.X)
        yaw = 0.5 * np.arctan2(2 * self.X[:, 0, 1], self.X[:, 0, 0] - self.X[:, 1, 1])
        return read_only(np.sqrt(lam1), np.sqrt(np.maximum(lam2, 0.0)), yaw)

    def rectangle(self):
        """
        Length and width of the oriented rectangle with the ellipse's second moments.

        Notes
        -----
        A filled ellipse of semi-axis ``a`` has second moment ``a^2/4`` along it; a filled
        rectangle of side ``L`` has ``L^2/12``; equal moments give ``L = sqrt(3) a``.
        """
        major, minor, _ = self.axes()
        return np.sqrt(3.0) * major, np.sqrt(3.0) * minor

    @staticmethod
    def empty():
        """Return estimates with no object."""
        return Estimates(np.zeros(0, np.int64), np.zeros(0), np.zeros((0, 4)),
                         np.zeros((0, 4, 4)), np.zeros((0, 2, 2)), np.zeros(0),
                         np.zeros(0, np.int64), np.zeros(0))


@dataclass(frozen=True)
class FilterState:
    """
    Everything the filter carries from one scan to the next.

    Attributes
    ----------
    mixture : Mixture
        Posterior GGIW mixture.
    log_card : (N_max + 1,) array
        Posterior cardinality pmf (log).
    next_label : int
        Next unused track label.
    reported : (r,) int64 array
        Labels extracted in the last scan, ascending (reported once confirmed, see
        :meth:`confirmed_rows`); ``reported_scans`` counts consecutive scans,
        ``reported_hits`` how many of those returns updated it in (its birth scan
        included; a label split off another's far component counts from its next scan,
        the returns of the split scan having updated the other label),
        ``reported_origin`` (r, 2) is where each was first reported, ``reported_size``
        (r,) its semi-major axis then, and ``reported_travel`` (r,) the farthest it has
        been from there in a scan where returns updated it (m; coasting drift does not
        count).
    shown : (s,) int64 array
        Labels ever reported (shown to the user) that are still in the mixture or were
        shown less than ``extraction.handover_time`` ago, ascending; ``shown_pos`` (s, 2)
        is where each was last shown, ``shown_vel`` (s, 2) its velocity then and
        ``shown_elapsed`` (s,) how long ago (s). A label's next report must be reachable
        from there within ``extraction.max_speed`` and ``extraction.max_accel`` or it is a
        new object.
    label_clock : tuple of (float, int)
        ``(seconds ago, next_label then)`` at the start of each scan of the last
        ``extraction.handover_time`` seconds, oldest first: labels from the first
        ``next_label`` on were created in that time.
    pairs : (k, 2) int64 array
        Pairs of labels (smaller first) extracted as close parts in the last scan, and
        ``pair_runs`` (k,) in how many scans in a row (see :func:`_join_parts`).

    """

    mixture: Mixture
    log_card: np.ndarray
    next_label: int = 1
    reported: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    reported_scans: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    reported_origin: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    reported_travel: np.ndarray = field(default_factory=lambda: np.zeros(0))
    reported_size: np.ndarray = field(default_factory=lambda: np.zeros(0))
    reported_hits: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    shown: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    shown_pos: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    shown_vel: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    shown_elapsed: np.ndarray = field(default_factory=lambda: np.zeros(0))
    label_clock: tuple = ()
    pairs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.int64))
    pair_runs: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    dt: float = 0.1

    @staticmethod
    def initial(cfg: TrackerConfig) -> 'FilterState':
        """An empty scene: no components, cardinality certainly zero."""
        log_card = np.full(cfg.model.n_max + 1, NEG_INF)
        log_card[0] = 0.0
        return FilterState(Mixture.empty(), log_card)

    def confirmed_rows(self, ex: ExtractionConfig) -> np.ndarray:
        """
        Which ``reported`` labels are confirmed: extracted ``ex.confirm_scans`` scans in a
        row and updated by returns in ``ex.confirm_detections`` of them (M of N).

        A static spot that returns now and then (a far edge, a half-seen table leg) makes a
        label from one scan's returns that the filter keeps extracting for a few scans
        while it coasts; counting the scans alone showed it as an object for a scan or two,
        again each time the spot returned.
        """
        return ((self.reported_scans >= ex.confirm_scans)
                & (self.reported_hits >= ex.confirm_detections))

    def confirmed_travel(self, labels: np.ndarray, ex: ExtractionConfig) -> np.ndarray:
        """
        How far (m) each of ``labels`` has travelled beyond its own first extent (its
        semi-major axis when first reported), for those confirmed (:meth:`confirmed_rows`);
        -1 for the others. A static object whose returns are learned as background one
        side after the other sees its centre shift by up to its own size; that is not
        travel.
        """
        out = np.full(len(labels), -1.0)
        if len(labels) and len(self.reported):
            at, found = _find_sorted(self.reported, labels)
            ok = found & self.confirmed_rows(ex)[at]
            out[ok] = np.maximum(self.reported_travel[at[ok]] - self.reported_size[at[ok]],
                                 0.0)
        return out


@dataclass
class StepDiagnostics:
    """Counts of one filter step (filled by update_state)."""

    detections: int = 0
    partitions: int = 0
    cells: int = 0
    pairs: int = 0
    components: int = 0
    births: int = 0
    capped_partitions: int = 0
    capped_cells: int = 0
    capped_components: int = 0
    oversized: int = 0
    fused_labels: int = 0
    joined_labels: int = 0
    relabelled: int = 0
    handed_over: int = 0
    grouped: int = 0


def sensor_noise(cfg: TrackerConfig) -> np.ndarray:
    """Sensor noise covariance R (m^2), read-only."""
    return _noise(cfg.model.sigma_range)


@cached_tables(maxsize=8)
def _noise(sigma_range: float) -> np.ndarray:
    """``sigma_range^2 I``."""
    return sigma_range ** 2 * np.eye(2)


# the Poisson clutter cardinality pmf (log): asked for on every scan with the same few
# (rate, size) arguments
_clutter_log_pmf = cached_tables(maxsize=256)(poisson_log_pmf)


def region_births(cfg: TrackerConfig, first_label: int) -> Mixture:
    """Birth components of the configured birth regions (x, y, std triples)."""
    if not len(cfg.birth.regions):
        return Mixture.empty()                  # the default: no array work on each scan
    reg = np.asarray(cfg.birth.regions, dtype=float).reshape(-1, 3)
    k = len(reg)
    b = cfg.birth
    P = np.zeros((k, 4, 4))
    P[:, 0, 0] = P[:, 1, 1] = reg[:, 2] ** 2
    P[:, 2, 2] = P[:, 3, 3] = b.velocity_std ** 2
    m = np.zeros((k, 4))
    m[:, :2] = reg[:, :2]
    X0 = (b.extent_semi_axis ** 2) * np.eye(2)
    v = np.full(k, b.dof)
    V = np.broadcast_to((b.dof - IW_OFFSET) * X0, (k, 2, 2)).copy()
    alpha = np.full(k, b.rate_shape)
    return Mixture(np.full(k, b.weight), alpha, alpha / b.expected_rate, m, P, v, V,
                   np.arange(first_label, first_label + k, dtype=np.int64))


def predict_state(state: FilterState, dt: float, cfg: TrackerConfig) -> FilterState:
    """
    Predict the mixture and cardinality ``dt`` seconds ahead; add region births.

    The cardinality prediction includes the Poisson birth of the region components and of
    the uniform birth intensity that :func:`update_state` evaluates per cell.
    """
    mc = cfg.model
    survivors = predict(state.mixture, dt, mc.p_survival, mc.sigma_accel, mc.tau_rate,
                        mc.tau_extent)
    regions = region_births(cfg, state.next_label)
    next_label = state.next_label + len(regions)
    p_s = mc.p_survival ** dt
    birth_mean = float(np.sum(regions.w)) + birth_intensity(cfg, dt)
    log_card = state.log_card
    if len(log_card) != mc.n_max + 1:                 # N_max changed while running
        log_card = resize_cardinality(log_card, mc.n_max)
    log_card = predict_cardinality(log_card, p_s, birth_mean)
    return evolve(state, mixture=Mixture.concat([survivors, regions]), log_card=log_card,
                  next_label=next_label, dt=dt)


def birth_intensity(cfg: TrackerConfig, dt: float) -> float:
    """Expected number of objects appearing anywhere in ``dt`` seconds."""
    return cfg.birth.rate * max(dt, 1e-3)


def _gates(mix: Mixture, cfg: TrackerConfig, min_weight: float = 0.5):
    """
    Inverse gate covariances of every component (for :func:`gate_pairs`) and the
    confident predictions for partitioning: centres, gates and rates of the heaviest
    component of each label of weight ``>= min_weight`` (None if there is none). Both
    sets of 2x2 matrices are inverted in one call.
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
    n = len(mix)
    inverses = inv2(np.concatenate([G, mix.P[best, :2, :2] + mix.expected_extent(best) + R]))
    return inverses[:n], {
        'centre': mix.m[best, :2],
        'gate_inv': inverses[n:],
        'gate': gate_threshold(cfg),
        'rate': mix.expected_rate()[best],
    }


def _birth_prior(stats, cfg: TrackerConfig, area: float) -> Mixture:
    """
    One GGIW per cell standing for the uniform birth intensity at that cell.

    Notes
    -----
    The birth intensity is uniform in position over the clutter area ``A``. For a cell
    ``W`` its position integral is evaluated with a component centred at the cell mean whose
    position covariance ``s^2 I`` has the uniform's density at its centre,
    ``1 / (2 pi s^2) = 1 / A``; everything else (velocity, rate, extent) is the birth prior.
    The extent prior mean is the floor semi-axis circle; its few degrees of freedom let the
    cell's own scatter decide (same ``rho`` as the update: trap 2).
    """
    b = cfg.birth
    k = len(stats.n)
    P0, V0 = _birth_row(area, b.velocity_std, b.extent_semi_axis, b.dof)
    m = np.zeros((k, 4))
    m[:, :2] = stats.mean
    v = np.full(k, b.dof)
    alpha = np.full(k, b.rate_shape)
    beta = alpha / b.expected_rate
    return Mixture(np.ones(k), alpha, beta, m, P0.repeat(k, axis=0), v, V0.repeat(k, axis=0),
                   np.zeros(k, dtype=np.int64))


@cached_tables(maxsize=16)             # constant while the field of view and config are
def _birth_row(area: float, velocity_std: float, extent_semi_axis: float, dof: float):
    """Position-velocity covariance (1, 4, 4) and IW scale (1, 2, 2) of a birth row."""
    P = np.zeros((1, 4, 4))
    P[:, 0, 0] = P[:, 1, 1] = area / (2.0 * np.pi)
    P[:, 2, 2] = P[:, 3, 3] = velocity_std ** 2
    X0 = (extent_semi_axis ** 2) * np.eye(2)
    return P, ((dof - IW_OFFSET) * X0)[None]


def update_state(state: FilterState, points: np.ndarray, p_d: np.ndarray, cfg: TrackerConfig,
                 rate_scale: np.ndarray | None = None, clutter_area: float | None = None,
                 visibility: np.ndarray | None = None,
                 centroid_offset: np.ndarray | None = None, pair_p_d=None):
    """
    Multi-object update of a predicted state with one scan's detections.

    Parameters
    ----------
    state : FilterState
        Output of :func:`predict_state`.
    points : (m, 2) array
        Detections (m).
    p_d : (n,) array
        Probability of detection of each predicted component.
    cfg : TrackerConfig
    rate_scale : (n,) array, optional
        Factor on each component's expected detections this scan (visible fraction).
    clutter_area : float, optional
        Area (m^2) clutter and births are spread over; ``model.surveillance_area`` if omitted.
    visibility : (n,) array, optional
        Visible fraction of each component, carried into the estimates.
    centroid_offset : (n, 2) array, optional
        Expected offset of each component's visible centroid (see ``update_pairs``).
    pair_p_d : callable, optional
        ``pair_p_d(mix, comp, m_updated, P_updated) -> (k,)`` p_D of each (component,
        cell) pair at its updated position; by default ``p_d[comp]``. ``p_d`` itself is
        still what the missed-detection factor uses.

    Returns
    -------
    state : FilterState
    estimates : Estimates
        The confirmed labels, with the thin pieces of one contour reported as one object
        (:func:`group_segments`).
    diagnostics : StepDiagnostics

    Raises
    ------
    ValueError
        If a detection is not finite (the pipeline's scan conversion never passes one).

    Notes
    -----
    The components of the update are the predicted mixture plus one row for the uniform
    birth intensity (weight ``birth.rate * dt``); its detected hypotheses become new tracks,
    so birth is driven by the cells the existing tracks explain poorly. New components from
    cells that share detections share a label, so that the overlapping cells of one new
    object merge into one track.

    """
    mc = cfg.model
    mix = state.mixture
    n_comp = len(mix)
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    if not np.isfinite(points).all():
        # the pipeline's scan conversion masks and counts such beams; a direct caller
        # gets told here rather than by whatever numeric routine meets them first
        bad = int((~np.isfinite(points).all(axis=1)).sum())
        raise ValueError(f'update_state: detections must be finite; {bad} of '
                         f'{len(points)} rows are not')
    diag = StepDiagnostics(detections=len(points))
    R = sensor_noise(cfg)
    area = clutter_area if clutter_area else mc.surveillance_area
    p_d = np.asarray(p_d, dtype=float).reshape(n_comp)
    if rate_scale is not None:
        rate_scale = np.maximum(np.asarray(rate_scale, dtype=float), 1e-3)
    gate_inv, confident = _gates(mix, cfg)
    pset = build_partitions(points, cfg.partition, confident)
    diag.partitions = len(pset.partitions)
    diag.cells = len(pset.cells)
    diag.capped_partitions = pset.capped_partitions
    diag.capped_cells = pset.capped_cells
    stats = cell_stats(points, pset.cells)
    n_cells = len(pset.cells)

    # existing components: gated (component, cell) pairs
    comp, cell = gate_pairs(mix, stats, mc.rho, R, gate_threshold(cfg), gate_inv)
    hidden = None
    if visibility is not None:
        hidden = np.minimum(np.maximum(1.0 - visibility, 0.0), 1.0)
    # existing components and the birth row (one GGIW per cell) in one batched update
    birth_prior = _birth_prior(stats, cfg, area)
    both = Mixture.concat([mix, birth_prior]) if n_comp else birth_prior
    bcell = np.arange(n_cells)
    upd_all = update_pairs(both, np.concatenate([comp, n_comp + bcell]), stats,
                           np.concatenate([cell, bcell]), mc.rho, R,
                           _pad(rate_scale, n_cells, 1.0), _pad(hidden, n_cells, 0.0),
                           _pad(centroid_offset, n_cells, 0.0))
    k = len(comp)
    pair_lik, birth_lik = upd_all.log_lik[:k], upd_all.log_lik[k:]
    p_d_pair = (p_d[comp] if pair_p_d is None
                else pair_p_d(mix, comp, upd_all.m[:k], upd_all.P[:k]))
    keep = p_d_pair > 0
    pair_rows = None                           # rows of upd_all holding the pairs kept
    if not np.logical_and.reduce(keep):
        pair_rows = keep.nonzero()[0]
        comp, cell, p_d_pair, pair_lik = comp[keep], cell[keep], p_d_pair[keep], pair_lik[keep]
    diag.pairs = len(comp)
    log_pd0 = _log_constant(cfg.detection.p_d0)

    log_g = np.full((n_comp + 1, n_cells), NEG_INF)
    log_g[comp, cell] = np.log(p_d_pair) + pair_lik
    log_g[n_comp, :] = np.where(stats.n >= cfg.birth.min_points, log_pd0 + birth_lik,
                                NEG_INF)
    mu_b = birth_intensity(cfg, state.dt)
    with np.errstate(divide='ignore'):
        log_w = np.concatenate([np.log(mix.w), [np.log(mu_b)]])
        log_qd = np.concatenate([log_miss_factor(mix, p_d, rate_scale),
                                 [_birth_log_miss_factor(cfg)]])
    cell_log_c = -stats.n * np.log(area)
    if mc.mode == 'cphd':
        k_most = max(map(len, pset.partitions), default=0)
        out = cphd_update(log_w, log_qd, log_g, cell_log_c, stats.n, pset.partitions,
                          state.log_card, _clutter_log_pmf(mc.clutter_rate, k_most + 1))
    else:
        out = phd_update(log_w, log_qd, log_g, cell_log_c, stats.n, pset.partitions,
                         mc.clutter_rate, mc.n_max)

    # posterior mixture: missed components, (component, cell) updates, births
    prune = cfg.reduction.prune_weight
    w_missed = np.exp(out.log_w_missed[:n_comp])
    w_det = np.exp(out.log_w_detected[comp, cell])
    sel = (w_det >= prune).nonzero()[0]
    w_birth = np.exp(out.log_w_detected[n_comp, :])
    bsel = (w_birth >= cfg.birth.min_weight).nonzero()[0]
    born, next_label = _label_births(pset, bsel, state.next_label,
                                     *_cell_claims(mix, comp, cell, w_det, n_cells),
                                     w_birth)
    diag.births = len(set(born.tolist()))
    # the detected pairs kept, then the births: one gather from the batched update
    rows = np.concatenate([sel if pair_rows is None else pair_rows[sel], k + bsel])
    posterior = Mixture.concat([
        mix.with_weights(w_missed),
        upd_all.take(rows).mixture(np.concatenate([w_det[sel], w_birth[bsel]]),
                                   np.concatenate([mix.label[comp[sel]], born]))])

    n_det = _detections_per_label(mix, comp, cell, w_det, w_missed, stats)
    # a new label was made from returns: the size of its heaviest birth cell
    for lab, c in _birth_cells(born, bsel, w_birth, state.next_label):
        n_det[lab] = int(stats.n[c])
    vis_of = {}
    if visibility is not None:
        for i in range(n_comp):
            vis_of.setdefault(int(mix.label[i]), float(visibility[i]))

    oversized = _implausible(posterior, cfg)
    diag.oversized = int(np.count_nonzero(oversized))
    if diag.oversized:
        posterior = posterior.take(~oversized)
    reduced, capped = reduce_mixture(posterior, prune, cfg.reduction.merge_distance,
                                     cfg.reduction.max_components)
    reduced, diag.fused_labels = _fuse_duplicate_labels(
        reduced, cfg.reduction.merge_distance, cfg.reduction.fuse_weight, state.reported,
        state.reported_scans)
    reduced, next_label = _split_labels(reduced, cfg.reduction.split_weight,
                                        cfg.reduction.merge_distance, next_label)
    diag.capped_components = capped
    diag.components = len(reduced)

    new_state = evolve(state, mixture=reduced, log_card=out.log_card, next_label=next_label)
    candidates = extract(new_state, cfg, n_det, vis_of)
    new_state, candidates, diag.relabelled = _relabel_jumps(state, new_state, candidates, cfg)
    new_state, candidates, record, diag.handed_over = _hand_over(state, new_state, candidates,
                                                                 cfg)
    new_state = _record_reports(record, new_state, candidates)
    joined = forming = NO_LABELS
    if cfg.reduction.pair_scans:
        new_state, candidates, joined, forming = _join_parts(new_state, candidates, cfg)
        diag.joined_labels = len(joined)
    # report a label once confirmed (M of N); a part never shown waits while its pair forms
    confirmed = new_state.confirmed_rows(cfg.extraction)
    if len(forming):
        confirmed &= ~(_find_sorted(np.sort(forming), candidates.label)[1]
                       & ~_find_sorted(state.shown, candidates.label)[1])
    shown = candidates.take(confirmed)
    new_state = _remember_shown(state, new_state, shown, cfg.extraction.handover_time, joined)
    # the filter's own estimates are what the shown record keeps; the report groups the
    # pieces of one contour
    shown, diag.grouped = group_segments(shown, new_state.reported_scans[confirmed],
                                         cfg.extraction.group_gap,
                                         cfg.extraction.group_speed)
    return new_state, shown, diag


def _join_parts(state: FilterState, est: Estimates, cfg: TrackerConfig):
    """
    Make one track of two extracted labels that have stayed together as parts of one
    object (a walker's two legs).

    Two extracted labels are a candidate pair when one of them is part-sized (semi-major
    axis at most ``reduction.pair_semi_axis``), their centres are within
    ``reduction.pair_distance`` and their velocities differ by at most
    ``reduction.pair_speed`` (nearest pairs first, one to one). A pair that has been one
    in ``reduction.pair_scans`` scans in a row is one object seen as two: their labels'
    heaviest components become one (:func:`join_parts`) under the senior label (reported
    in more scans in a row; then the smaller label) and the other label's components are
    dropped. The junior label leaves the estimates, the report record and (in
    :func:`_remember_shown`) the shown record. The junior of a pair still forming is
    returned too: a label never shown waits to be shown while its pair forms
    (:func:`update_state`), so a part born beside its object is joined before it is ever
    shown, also when the pair forms a scan or two after its birth. In CPHD mode the
    cardinality pmf loses the dropped weight (:func:`cphd.thin_cardinality`). The
    senior's estimate this scan is as extracted; the next scan starts from the joined
    component.

    ``state``'s report record must be ``est``'s (:func:`_record_reports`). Returns the
    state, the estimates, the junior labels joined (ascending) and the juniors of the
    pairs still forming.

    Notes
    -----
    A scanner at leg height sees a walker as two legs. The filter often tracks each leg
    on its own: sub-partitioning then keeps them apart, since it splits a cell among the
    confident tracks that gate it (which is what keeps two people apart). A walker
    tracked as one ellipse is split again when a wide stride puts its legs in cells of
    their own: the far leg is born anew next to it. A walker's legs stay within about
    0.6 m of each other, and one swings at up to twice the walking speed while the other
    stands. Pairing leg-sized reports into one report scan by scan, without a record,
    made the report change label whenever the stride took the legs apart.
    """
    rc = cfg.reduction
    joined = forming = NO_LABELS
    pairs, runs = np.zeros((0, 2), np.int64), NO_LABELS
    if len(est) > 1:
        semi = est.axes()[0]
        i, j = np.triu_indices(len(est), 1)
        d = est.m[i, :2] - est.m[j, :2]
        dv = est.m[i, 2:] - est.m[j, 2:]
        d2 = np.add.reduce(d * d, axis=1)
        ok = ((np.minimum(semi[i], semi[j]) <= rc.pair_semi_axis)
              & (d2 <= rc.pair_distance ** 2)
              & (np.add.reduce(dv * dv, axis=1) <= rc.pair_speed ** 2)).nonzero()[0]
        taken, rows = set(), []
        for k in ok[d2[ok].argsort(kind='stable')].tolist():
            if i[k] not in taken and j[k] not in taken:
                taken.update((i[k], j[k]))
                rows.append((i[k], j[k]))
        rows = np.array(rows, dtype=np.int64).reshape(-1, 2)
        pairs = est.label[rows]                        # labels ascending: smaller first
        runs = np.ones(len(rows), np.int64)
        for n, (a, b) in enumerate(pairs.tolist()):
            was = ((state.pairs[:, 0] == a) & (state.pairs[:, 1] == b)).nonzero()[0]
            if len(was):
                runs[n] += state.pair_runs[was[0]]
        # senior first in each row: reported in more scans in a row, then the smaller label
        swap = state.reported_scans[rows[:, 1]] > state.reported_scans[rows[:, 0]]
        rows[swap] = rows[swap][:, ::-1]
        ready = runs >= rc.pair_scans
        forming = est.label[rows[~ready, 1]]
        if np.logical_or.reduce(ready):
            state, est, joined = _join(state, est, rows[ready], cfg)
            pairs, runs = pairs[~ready], runs[~ready]
    return evolve(state, pairs=pairs, pair_runs=runs), est, joined, forming


def _join(state: FilterState, est: Estimates, rows: np.ndarray, cfg: TrackerConfig):
    """Join the labels of each pair of ``est`` rows (see :func:`_join_parts`)."""
    mix = state.mixture
    order, is_head, _ = mix.by_label()
    labels, _, weight = mix.per_label()
    heads = order[is_head]
    drop = np.zeros(len(mix), dtype=bool)
    joined, junior_rows, removed = [], [], 0.0
    for a, b in rows.tolist():                         # the senior first
        at = labels.searchsorted(est.label[[a, b]])
        w = weight[at]
        joined.append(join_parts(mix, heads[at], w, int(est.label[a])))
        drop |= (mix.label == est.label[a]) | (mix.label == est.label[b])
        junior_rows.append(b)
        removed += float(w.sum() - w.max())
    log_card = state.log_card
    if cfg.model.mode == 'cphd':
        log_card = thin_cardinality(log_card, removed)
    keep = np.ones(len(est), dtype=bool)
    keep[junior_rows] = False
    state = evolve(state, mixture=Mixture.concat([mix.take(~drop)] + joined),
                   log_card=log_card, reported=state.reported[keep],
                   reported_scans=state.reported_scans[keep],
                   reported_origin=state.reported_origin[keep],
                   reported_travel=state.reported_travel[keep],
                   reported_size=state.reported_size[keep],
                   reported_hits=state.reported_hits[keep])
    return state, est.take(keep), np.sort(est.label[~keep])


def group_segments(est: Estimates, seniority: np.ndarray, gap: float, speed: float):
    """
    Report the thin pieces of one object's contour as that object.

    A laser sees a car across a corner as an L: its long side and its end. Two thin
    ellipses explain those returns far better than one ellipse over the car does (the
    model spreads detections over the extent, the scanner sees the contour), so the filter
    tracks two thin objects. Pieces at most ``SEGMENT_MAX_SEMI_MINOR`` thick and at least
    ``SEGMENT_MIN_SEMI_MAJOR`` long whose ends are within ``gap`` of each other and whose
    velocities differ by at most ``speed`` are reported as one object: the rectangle
    around them in the frame of the longest piece (its extent the rectangle's second
    moments), moving at their rate-weighted velocity, under the label of the most senior
    piece (the most ``seniority``, reported scans in a row; then the smaller label), its
    position covariance that piece's. Existence and visibility are the pieces' largest,
    rate and detections their sums.

    Returns the estimates (ascending labels) and the number of pieces grouped into
    another's report.
    """
    k = len(est)
    if gap <= 0 or k < 2:
        return est, 0
    # the semi-major axis squared is at most the trace: people are ruled out at once
    X = est.X
    long_ = (X[:, 0, 0] + X[:, 1, 1] >= SEGMENT_MIN_SEMI_MAJOR ** 2).nonzero()[0]
    if len(long_) < 2:
        return est, 0
    major, minor, yaw = (a[long_] for a in est.axes())
    thin = (minor <= SEGMENT_MAX_SEMI_MINOR) & (major >= SEGMENT_MIN_SEMI_MAJOR)
    seg, major, minor, yaw = long_[thin], major[thin], minor[thin], yaw[thin]
    if len(seg) < 2:
        return est, 0
    u = np.stack([np.cos(yaw), np.sin(yaw)], axis=1)
    half = (0.5 * np.sqrt(3.0)) * major                # half the rectangle's length
    centre = est.m[seg, :2]
    ends = np.concatenate([centre + half[:, None] * u, centre - half[:, None] * u])  # (2s, 2)
    s = len(seg)
    d = ends[:, None, :] - ends[None, :, :]
    d = np.sqrt(np.add.reduce(d * d, axis=2)).reshape(2, s, 2, s).min(axis=(0, 2))
    dv = est.m[seg, None, 2:] - est.m[None, seg, 2:]
    dv = np.sqrt(np.add.reduce(dv * dv, axis=2))
    near = (d <= gap) & (dv <= speed)
    np.fill_diagonal(near, False)
    if not near.any():
        return est, 0
    parent = list(range(s))
    for i, j in zip(*near.nonzero()):
        union_min(parent, int(i), int(j))
    roots = np.array([find_root(parent, i) for i in range(s)])
    keep = np.ones(k, dtype=bool)
    out = Estimates(est.label.copy(), est.existence.copy(), est.m.copy(), est.P.copy(),
                    est.X.copy(), est.rate.copy(), est.num_detections.copy(),
                    est.visibility.copy())
    grouped = 0
    for r in np.unique(roots):
        members = (roots == r).nonzero()[0]
        if len(members) < 2:
            continue
        rows = seg[members]
        # the longest piece carries the report (ungrouped, it is the one nearest the
        # object), then the most senior: most scans in a row, then the oldest
        head = rows[np.lexsort((est.label[rows], -seniority[rows], -major[members]))[0]]
        ux, uy = u[members[np.argmax(major[members])]]
        frame = np.array([[ux, -uy], [uy, ux]])        # the longest piece's axis, its normal
        pts = np.concatenate([ends[members], ends[s + members]]) @ frame
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        length = hi[0] - lo[0]
        width = hi[1] - lo[1] + np.sqrt(3.0) * minor[members].max()
        w = np.maximum(est.rate[rows], 1e-9)
        out.m[head, :2] = frame @ (0.5 * (lo + hi))
        out.m[head, 2:] = (w[:, None] * est.m[rows, 2:]).sum(axis=0) / w.sum()
        out.X[head] = frame @ np.diag([length ** 2 / 3.0, width ** 2 / 3.0]) @ frame.T
        out.existence[head] = est.existence[rows].max()
        out.visibility[head] = est.visibility[rows].max()
        out.rate[head] = est.rate[rows].sum()
        out.num_detections[head] = est.num_detections[rows].sum()
        keep[rows] = False
        keep[head] = True
        grouped += len(rows) - 1
    return out.take(keep), grouped


def _relabel_jumps(old: FilterState, new: FilterState, est: Estimates, cfg: TrackerConfig):
    """
    Give a new label to each extracted label that could not have got where it is.

    A label last shown at ``p`` ``t`` seconds ago and now extracted at ``q`` moved at
    least ``|q - p| / t``. Farther than ``extraction.max_speed * t +
    extraction.jump_slack`` it is not the object that was shown: a track that coasted
    unseen while its position uncertainty grew to metres has taken the returns of a
    newcomer (the CV model's white acceleration lets it; a walker does not run at
    6 m/s). Likewise when ``q`` is farther than ``extraction.max_accel * t^2 / 2 +
    jump_slack`` from ``p + v t``, ``v`` the velocity it was shown with: an object at
    rest does not cover 3 m in 0.4 s. The estimate stays where the filter put it, under
    a fresh label that must be confirmed like any new object, and the old id is not
    reused.

    Returns the state (mixture relabelled, ``next_label`` advanced), the estimates (still
    in ascending label order) and the number of labels changed.

    Notes
    -----
    Seen on the leg_tracker positive_1 recording: ids that jumped 4.2 m in 0.4 s and
    8.6 m in 1.2 s (since last shown) onto people who had just entered. On the
    obstacle_detector recording, tracks on static posts jumped 3-4 m to another post
    within the default 15 m/s.
    """
    if not len(old.shown) or not len(est):
        return new, est, 0
    ex = cfg.extraction
    at, known = _find_sorted(old.shown, est.label)
    d = est.m[:, :2] - old.shown_pos[at]
    t = old.shown_elapsed[at] + new.dt
    jumped = known & (np.sqrt(np.add.reduce(d * d, axis=1)) > _speed_reach(ex, t))
    if ex.max_accel > 0:
        d -= old.shown_vel[at] * t[:, None]          # from where its velocity carried it
        jumped |= known & (np.sqrt(np.add.reduce(d * d, axis=1))
                           > 0.5 * ex.max_accel * t * t + ex.jump_slack)
    if not np.logical_or.reduce(jumped):
        return new, est, 0
    bad = est.label[jumped]
    fresh = new.next_label + np.arange(len(bad))
    mix = new.mixture
    label = mix.label.copy()
    at, hit = _find_sorted(bad, label)                   # est.label is ascending
    label[hit] = fresh[at[hit]]
    est_label = est.label.copy()
    est_label[jumped] = fresh
    # the fresh labels are the largest: move them to the end, so the estimates stay in
    # ascending label order as extract gives them (the shown record searches them)
    order = est_label.argsort(kind='stable')
    return (evolve(new, mixture=evolve(mix, label=label),
                   next_label=new.next_label + len(bad)),
            evolve(est, label=est_label).take(order), len(bad))


def _speed_reach(ex, t):
    """How far an id may be from where it was shown ``t`` seconds ago under the speed
    limit: ``extraction.max_speed * t + extraction.jump_slack``."""
    return ex.max_speed * t + ex.jump_slack


def _remember_shown(old: FilterState, new: FilterState, shown: Estimates,
                    handover_time: float = 0.0, joined=NO_LABELS) -> FilterState:
    """
    Where, at what velocity and how long ago each label was last shown: labels still in
    the mixture, and those shown less than ``handover_time`` ago (they may be handed
    over, see :func:`_hand_over`), but not the ``joined`` labels (ascending): they are
    part of another object now, not lost (:func:`_join_parts`). Also the label counter
    of the last ``handover_time`` seconds.
    """
    alive = new.mixture.per_label()[0]                 # ascending, cached by extract
    elapsed = old.shown_elapsed + new.dt
    keep = ((_find_sorted(alive, old.shown)[1] | (elapsed <= handover_time))
            & ~_find_sorted(shown.label, old.shown)[1])
    if len(joined):
        keep &= ~_find_sorted(joined, old.shown)[1]
    label = np.concatenate([old.shown[keep], shown.label])
    pos = np.concatenate([old.shown_pos[keep], shown.m[:, :2]])
    vel = np.concatenate([old.shown_vel[keep], shown.m[:, 2:]])
    elapsed = np.concatenate([elapsed[keep], np.zeros(len(shown))])
    order = label.argsort(kind='stable')
    dt = new.dt
    clock = tuple((ago + dt, lab) for ago, lab in old.label_clock if ago + dt <= handover_time)
    return evolve(new, shown=label[order], shown_pos=pos[order], shown_vel=vel[order],
                  shown_elapsed=elapsed[order], label_clock=clock + ((0.0, old.next_label),))


def _hand_over(old: FilterState, new: FilterState, est: Estimates, cfg: TrackerConfig):
    """
    Give a lost id to a young object that appeared where the lost one would be.

    A label shown less than ``extraction.handover_time`` ago that is not extracted now is
    lost. A label created less than ``handover_time`` ago and extracted now is young. A
    young label within ``extraction.handover_distance`` of a lost label's last shown
    position, carried on at its last shown velocity, takes the lost label (nearest pairs
    first, one to one), unless the speed limit of :func:`_relabel_jumps` would call the
    move a jump, or the lost label is the newer of the two: an id passes only to a label
    created after it. Established labels never take another's id, so two tracked objects
    that pass each other keep theirs.

    In the mixture the two labels swap: the young object's components carry the old id
    on, the lost label's fading components carry the young one. The young label's report
    count passes to the old id when the old id was not extracted in the last scan, so a
    handed-over id is confirmed as the young one would have been.

    Returns the state, the estimates (ascending labels), the report record to continue
    from (``old`` with the young labels' counts renamed) and the number of handovers.

    Notes
    -----
    Seen at leg height (the leg_tracker demo): a walker tracked on one leg while the other
    is hidden; the other leg steps out 0.3-0.5 m ahead, is split off under a new label,
    and the first leg's track fades when that leg is hidden in turn. Without a handover
    the walker changes id at every such step. On the Freiburg recording two young labels
    on one walker, just after the background warm-up, traded ids every scan for 26 scans
    (the one extracted took the id of the other, shown the scan before) until both were
    older than the window; an id passing only to a newer label ends that.
    """
    window = cfg.extraction.handover_time
    if window <= 0 or not len(old.shown) or not len(est):
        return new, est, old, 0
    dt = new.dt
    extracted = set(est.label.tolist())
    lost = [i for i, (lab, ago) in enumerate(zip(old.shown.tolist(),
                                                 old.shown_elapsed.tolist()))
            if ago + dt <= window and lab not in extracted]
    if not lost:
        return new, est, old, 0
    # labels created this scan are >= old.next_label, earlier ones in the window >= the
    # counter at the window's start
    first_young = next((lab for ago, lab in old.label_clock if ago + dt <= window),
                       old.next_label)
    young = (est.label >= first_young).nonzero()[0]
    if not len(young):
        return new, est, old, 0
    ex = cfg.extraction
    lost = np.array(lost)
    elapsed = old.shown_elapsed[lost] + dt
    pos, last = est.m[young, None, :2], old.shown_pos[None, lost]
    d = pos - (last + old.shown_vel[None, lost] * elapsed[None, :, None])
    dist = np.sqrt(np.add.reduce(d * d, axis=2))       # (young, lost)
    # and never farther than the speed limit lets an id move (see _relabel_jumps)
    d = pos - last
    reach = _speed_reach(ex, elapsed)
    near = ((dist <= ex.handover_distance)
            & (np.sqrt(np.add.reduce(d * d, axis=2)) <= reach[None, :])
            & (est.label[young][:, None] > old.shown[lost][None, :])).nonzero()
    if not len(near[0]):
        return new, est, old, 0
    order = dist[near].argsort(kind='stable')
    taken_y, taken_l, pairs = set(), set(), []
    for yi, li in zip(near[0][order].tolist(), near[1][order].tolist()):
        if yi not in taken_y and li not in taken_l:
            taken_y.add(yi)
            taken_l.add(li)
            pairs.append((int(est.label[young[yi]]), int(old.shown[lost[li]])))
    mix = new.mixture
    label = mix.label.copy()
    est_label = est.label.copy()
    rec = old.reported.copy()
    for y, a in pairs:
        is_y, is_a = mix.label == y, mix.label == a
        label[is_y], label[is_a] = a, y
        est_label[est.label == y] = a
        if not (rec == a).any():
            rec[rec == y] = a
    order = est_label.argsort(kind='stable')
    return (evolve(new, mixture=evolve(mix, label=label)),
            evolve(est, label=est_label).take(order), evolve(old, reported=rec), len(pairs))


def _find_sorted(ascending: np.ndarray, a: np.ndarray):
    """
    ``(at, found)``: where each of ``a`` is in the ascending array ``ascending`` and
    whether it is there at all (``at`` is a valid index either way). For the few labels
    of a scan: ``np.isin`` would sort both arrays again.
    """
    if not len(ascending):
        return np.zeros(len(a), dtype=np.int64), np.zeros(len(a), dtype=bool)
    at = np.minimum(ascending.searchsorted(a), len(ascending) - 1)
    return at, ascending[at] == a


def _record_reports(old: FilterState, new: FilterState, est: Estimates) -> FilterState:
    """Carry per-label report counts, scans with returns, first positions and distances
    travelled."""
    index = {int(lab): i for i, lab in enumerate(old.reported.tolist())}
    # each label's row in the last report (-1: reported for the first time)
    prev = np.array([index.get(lab, -1) for lab in est.label.tolist()], dtype=np.int64)
    again = prev >= 0
    i = prev[again]
    scans = np.ones(len(est), dtype=np.int64)
    scans[again] = old.reported_scans[i] + 1
    origin = est.m[:, :2].copy()
    origin[again] = old.reported_origin[i]
    size = np.empty(len(est))
    size[again] = old.reported_size[i]
    if len(i) < len(est):                          # the semi-major axis of the new ones
        size[~again] = np.sqrt(eig2(est.X[~again])[0])
    d = est.m[:, :2] - origin
    travel = np.sqrt(np.add.reduce(d * d, axis=1))     # as np.linalg.norm(d, axis=1) does
    # only where returns placed it: a coasting label drifts with its predicted velocity
    travel[est.num_detections <= 0] = 0.0
    travel[again] = np.maximum(travel[again], old.reported_travel[i])
    hits = (est.num_detections > 0).astype(np.int64)
    hits[again] += old.reported_hits[i]
    return evolve(new, reported=est.label.copy(), reported_scans=scans, reported_origin=origin,
                  reported_travel=travel, reported_size=size, reported_hits=hits)


def _pad(a, n: int, fill: float):
    """``a`` with ``n`` rows of ``fill`` appended (None stays None)."""
    if a is None:
        return None
    return np.concatenate([a, np.full((n,) + a.shape[1:], fill)])


def _birth_log_miss_factor(cfg: TrackerConfig) -> float:
    """``log q_D`` of the birth intensity: ``1 - p_D0 (1 - (beta/(beta+1))^alpha)``."""
    return _birth_log_miss(cfg.birth.rate_shape, cfg.birth.expected_rate, cfg.detection.p_d0)


@lru_cache(maxsize=64)                 # constant while the configuration is
def _birth_log_miss(alpha: float, expected_rate: float, p_d0: float) -> float:
    beta = alpha / expected_rate
    log_e0 = alpha * (np.log(beta) - np.log1p(beta))
    return float(np.log1p(p_d0 * np.expm1(log_e0)))


def _implausible(mix: Mixture, cfg: TrackerConfig) -> np.ndarray:
    """
    Components to drop: larger than any object tracked here (walls, clutter lines), or
    coasted until their position is unknown within metres (they could only claim
    far-away returns).
    """
    major2, _ = eig2(mix.expected_extent())
    pos_var = np.maximum(mix.P[:, 0, 0], mix.P[:, 1, 1])
    return ((major2 > cfg.reduction.max_semi_axis ** 2)
            | (pos_var > cfg.reduction.max_position_std ** 2))


def gate_threshold(cfg: TrackerConfig) -> float:
    """Squared Mahalanobis gate of (component, cell) pairs (chi-square, 2 dof)."""
    return _chi2_2dof_ppf(cfg.partition.gate_probability)


@lru_cache(maxsize=64)                 # asked for twice a scan with the same probability
def _chi2_2dof_ppf(p: float) -> float:
    """``chi2.ppf(p, 2) = -2 log(1 - p)``."""
    return float(-2.0 * np.log1p(-p))


@lru_cache(maxsize=64)
def _log_constant(x: float) -> float:
    """``log x`` of a configured constant (a probability), computed once."""
    return np.log(x)


def _cell_claims(mix: Mixture, comp, cell, w_det, n_cells):
    """
    The label with the most detected weight on each cell, and that weight (0 if none),
    from the (component, cell) pairs.
    """
    claim = np.zeros(n_cells, dtype=np.int64)
    weight = np.zeros(n_cells)
    if not len(cell):
        return claim, weight
    labels, rank, _ = mix.per_label()
    per = np.zeros((len(labels), n_cells))
    np.add.at(per, (rank[comp], cell), w_det)
    best = weight_key(per).argmax(axis=0)             # ties: the first label
    return labels[best], per[best, np.arange(n_cells)]


def _label_births(pset, birth_cells, next_label, claim=None, claim_weight=None,
                  birth_weight=None):
    """
    Labels of new components: cells that share detections get one label.

    Overlapping cells (a cell and its sub-cells from other partitions) are alternative
    explanations of the same returns, so their birth hypotheses are one new object and
    merge; cells with no detection in common are different objects.

    A birth on a cell that an existing label explains with more weight than the birth is
    an alternative hypothesis of that object (a restart at zero velocity), not a new
    object: it takes that label. Otherwise a second label would follow the object and
    take it over whenever its fresh extent fits a scan better, a new id each time.
    """
    k = len(birth_cells)
    if not k:
        return np.zeros(0, dtype=np.int64), next_label
    out = np.zeros(k, dtype=np.int64)
    if claim is not None:
        claimed = claim_weight[birth_cells] > birth_weight[birth_cells]
        out[claimed] = claim[birth_cells[claimed]]
        free = (~claimed).nonzero()[0]
        if len(free) < k:
            out[free], next_label = _label_births(pset, birth_cells[free], next_label)
            return out, next_label
    parent = list(range(k))
    owner = {}
    for i, c in enumerate(birth_cells):
        for z in pset.cells[c].tolist():
            j = owner.setdefault(z, i)
            if j != i:
                union_min(parent, i, j)
    roots = np.array([find_root(parent, i) for i in range(k)])
    uniq, inverse = np.unique(roots, return_inverse=True)
    return (next_label + inverse).astype(np.int64), next_label + len(uniq)


def _birth_cells(born, bsel, w_birth, first_new: int):
    """``(label, cell)`` of each new label (``>= first_new``) and its heaviest birth cell
    (``born`` labels the birth cells ``bsel``; ``w_birth`` the weights of all cells;
    weights that tie but for their last bits order by row, :func:`weight_key`)."""
    new = (born >= first_new).nonzero()[0]
    if not len(new):
        return []
    order, is_head = group_heads(born[new], -weight_key(w_birth[bsel[new]]))
    head = new[order[is_head]]
    return list(zip(born[head].tolist(), bsel[head].tolist()))


def _detections_per_label(mix, comp, cell, w_det, w_missed, stats):
    """Size of each label's heaviest detected cell, where detection outweighs a miss."""
    if not len(comp):
        return {}
    labels, inv, _ = mix.per_label()
    pair_lab = inv[comp]
    detected = np.bincount(pair_lab, weights=w_det, minlength=len(labels))
    missed = np.bincount(inv, weights=w_missed, minlength=len(labels))
    order, is_head = group_heads(pair_lab, -weight_key(w_det))
    first = order[is_head]                               # each label's heaviest pair
    ok = detected[pair_lab[first]] > missed[pair_lab[first]]
    first = first[ok]
    return dict(zip(labels[pair_lab[first]].tolist(), stats.n[cell[first]].tolist()))


def _spread_inv(mix: Mixture, idx) -> np.ndarray:
    """Inverse of position covariance plus expected extent of components ``idx``: the
    metric in which a label's members are near their head (splitting, fusion)."""
    return inv2(mix.P[idx, :2, :2] + mix.expected_extent(idx))


def _fuse_duplicate_labels(mix: Mixture, merge_distance: float, fuse_weight: float,
                           reported=None, reported_scans=None):
    """
    Give one label to labels that track the same object.

    Two labels whose heaviest components lie within the merge distance of each other
    (both ways, in the metric of :func:`_split_labels`: position covariance plus extent)
    and whose weights sum to at most ``fuse_weight`` are one object seen twice. With the
    default merge distance the heads are then closer than about twice the extent's
    spread, where two objects would overlap; and two *tracked* objects passing close
    (crossing, one behind the other) carry about one unit of weight each, so they stay
    apart.

    The label that stays is the senior one: reported in more consecutive scans
    (``reported`` labels with their ``reported_scans``), then the heavier, then the older
    (smaller) label;
    the other's components join it. The id a user sees is kept, whichever hypothesis is
    heavier at that moment.

    Returns the mixture and the number of labels fused away.

    Notes
    -----
    Seen on real recordings: one object born from two cells with no return in common
    (the halves of a sub-partition) got two labels; both then followed the whole object,
    splitting its weight (0.36 and 0.74), and a neighbour's label took it over when one
    of them faded. On the leg_tracker demo a walker's fading track and a fresh birth on
    the same legs were fused under the birth's label while the heavier label absorbed:
    the walker changed id. Seniority keeps it. Among labels not reported, the older had
    stayed: a light label left coasting on a static spot that flickers (shown there
    seconds before) got a detected component on a newcomer's returns metres away, and
    the newcomer took its id (2.5 m on obstacle_detector, 7.4 m on positive_1). The
    heavier, the birth that explains the returns, now stays.
    """
    if not len(mix) or fuse_weight <= 0:
        return mix, 0
    order, is_head, group = mix.by_label()
    if not group[-1]:
        return mix, 0                                  # a single label
    labels, _, weight = mix.per_label()
    # only labels light enough to pair with the lightest other one can take part
    two = np.partition(weight, 1)[:2]
    cand = (weight + np.where(weight == two[0], two[1], two[0]) <= fuse_weight).nonzero()[0]
    if len(cand) < 2:
        return mix, 0
    heads = order[is_head][cand]
    c = mix.m[heads, :2]
    inv_spread = _spread_inv(mix, heads)
    e = c[None, :, :] - c[:, None, :]                  # e[i, j] = c_j - c_i
    d2 = einsum('ijk,ikl,ijl->ij', e, inv_spread, e)    # in head i's metric
    close = (np.maximum(d2, d2.T) <= merge_distance)
    np.fill_diagonal(close, False)
    if not close.any():
        return mix, 0
    scans = np.zeros(len(cand), dtype=np.int64)
    if reported is not None and len(reported):
        at, ok = _find_sorted(labels, reported)
        full = np.zeros(len(labels), dtype=np.int64)
        full[at[ok]] = reported_scans[ok]
        scans = full[cand]
    # seniority: most scans reported, then the heavier, then the older label (cand is in
    # label order)
    w = weight[cand]
    senior = np.lexsort((np.arange(len(cand)), -weight_key(w), -scans))
    rank = np.empty(len(cand), dtype=np.int64)
    rank[senior] = np.arange(len(cand))
    into = np.arange(len(cand))
    total = w.copy()
    for i in senior.tolist():
        if into[i] != i:
            continue                                   # joined a more senior label
        for j in close[i].nonzero()[0].tolist():
            if into[j] == j and rank[j] > rank[i] and total[i] + total[j] <= fuse_weight:
                into[j] = i
                total[i] += total[j]
    fused = int(np.count_nonzero(into != np.arange(len(cand))))
    if not fused:
        return mix, 0
    target = np.arange(len(weight))
    target[cand] = cand[into]
    label = mix.label.copy()
    label[order] = labels[target[group]]
    return evolve(mix, label=label), fused


def _split_labels(mix: Mixture, split_weight: float, merge_distance: float, next_label: int):
    """
    Resolve labels whose components ended up far apart after merging.

    A far component (outside the merge distance of its label's heaviest) that is heavy
    becomes a new object with a fresh label (two pedestrians side by side separating); a
    light one is dropped: one object is not in two places, and keeping it makes the
    label's reported position jump between the two.
    """
    if not len(mix):
        return mix, next_label
    order, is_head, group = mix.by_label()
    if np.logical_and.reduce(is_head):
        return mix, next_label                         # one component a label (most scans)
    heads = order[is_head]
    e = mix.m[order, :2] - mix.m[heads[group], :2]
    d2 = einsum('ki,kij,kj->k', e, _spread_inv(mix, heads)[group], e)
    far = np.zeros(len(mix), dtype=bool)
    far[order] = (d2 > merge_distance) & ~is_head
    if not np.logical_or.reduce(far):
        return mix, next_label
    heavy = far & (mix.w >= split_weight)
    label = mix.label.copy()
    # fresh labels in order of weight, as the objects they stand for are found
    new = heavy.nonzero()[0]
    new = new[(-weight_key(mix.w[new])).argsort(kind='stable')]
    label[new] = next_label + np.arange(len(new))
    keep = ~(far & ~heavy)
    return evolve(mix, label=label).take(keep), next_label + len(new)


def extract(state: FilterState, cfg: TrackerConfig, n_det=None, visibility=None) -> Estimates:
    """
    Report the heaviest labels: ``MAP(p'(n))`` of them in CPHD mode, those heavier than
    ``extraction.phd_threshold`` in PHD mode; never one lighter than ``min_existence``.

    Each label is reported by its heaviest component.
    """
    mix = state.mixture
    if not len(mix):
        return Estimates.empty()
    by_lab, is_head, _ = mix.by_label()
    heads = by_lab[is_head]                            # one per label, labels ascending
    labels, _, weight = mix.per_label()
    order = (-weight_key(weight)).argsort(kind='stable')
    ex = cfg.extraction
    if cfg.model.mode == 'cphd':
        n_hat = int(state.log_card.argmax())
        chosen = order[:n_hat]
    else:
        chosen = order[weight[order] > ex.phd_threshold]
    chosen = chosen[weight[chosen] >= ex.min_existence]
    chosen = np.sort(labels[chosen])
    if not len(chosen):
        return Estimates.empty()
    at = labels.searchsorted(chosen)
    best, lab_w = heads[at], weight[at]
    n_det = n_det or {}
    visibility = visibility or {}
    return Estimates(
        label=chosen.astype(np.int64),
        existence=np.minimum(np.maximum(lab_w, 0.0), 1.0),
        m=mix.m[best],
        P=mix.P[best],
        X=mix.expected_extent(best),
        rate=mix.expected_rate()[best],
        num_detections=np.array([n_det.get(int(x), 0) for x in chosen], dtype=np.int64),
        visibility=np.array([visibility.get(int(x), 1.0) for x in chosen]),
    )


def filter_step(state: FilterState, points: np.ndarray, dt: float, cfg: TrackerConfig,
                p_d=None, clutter_area=None):
    """
    Predict, update, reduce and extract with a constant or given p_D (synthetic use).

    ``p_d`` may be a callable taking the predicted mixture and returning per-component
    probabilities; by default ``detection.p_d0`` for every component.
    """
    pred = predict_state(state, dt, cfg)
    if callable(p_d):
        pd = np.asarray(p_d(pred.mixture), dtype=float)
    else:
        pd = np.full(len(pred.mixture), cfg.detection.p_d0 if p_d is None else p_d)
    return update_state(pred, points, pd, cfg, clutter_area=clutter_area)
