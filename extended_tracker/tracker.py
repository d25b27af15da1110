"""
One filter step of the GGIW-CPHD (or PHD) tracker on Cartesian detections.

The state is data (:class:`~extended_tracker.state.FilterState`), passed in and returned.
The laser front end and the per-scan pipeline (:mod:`extended_tracker.pipeline`) call
:func:`predict_state` and :func:`update_state`; synthetic tests may call
:func:`filter_step` directly. What happens to the labels between extraction and report
(confirmation, jumps, hand-over, joined parts, grouped pieces) is in
:mod:`extended_tracker.identity`.
"""

from __future__ import annotations

from dataclasses import replace
from functools import lru_cache

import numpy as np


from .config import TrackerConfig
from .cphd import (
    add_cardinality, cphd_update, phd_update, poisson_log_pmf, predict_cardinality,
    resize_cardinality, thin_cardinality,
)
from .ggiw import (
    cell_stats, eig2, gate_covariance, gate_pairs, group_heads, inv2, IW_OFFSET,
    log_miss_factor, Mixture, predict, quad_form2, update_pairs, weight_key,
)
from .identity import (
    group_segments, hand_over, join_pairs, record_reports, relabel_jumps, remember_shown,
)
from .partition import build_partitions, find_root, union_min
from .reduction import reduce_mixture
from .tables import cached_tables
from .state import Estimates, FilterState, find_sorted, NEG_INF, NO_LABELS, StepDiagnostics


def sensor_noise(cfg: TrackerConfig) -> np.ndarray:
    """Sensor noise covariance R (m^2), read-only."""
    return _noise(cfg.model.sigma_range)


@cached_tables(maxsize=8)
def _noise(sigma_range: float) -> np.ndarray:
    """``sigma_range^2 I``."""
    return sigma_range ** 2 * np.eye(2)


# the Poisson clutter cardinality pmf (log): asked for on every scan with the clutter rate
# and the scan's number of detections, which repeat
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
    v = np.full(k, float(b.dof))
    V = np.broadcast_to((b.dof - IW_OFFSET) * X0, (k, 2, 2)).copy()
    alpha = np.full(k, float(b.rate_shape))
    return Mixture(np.full(k, float(b.weight)), alpha, alpha / b.expected_rate, m, P, v, V,
                   np.arange(first_label, first_label + k, dtype=np.int64))


def predict_state(state: FilterState, dt: float, cfg: TrackerConfig) -> FilterState:
    """
    Predict the mixture and cardinality ``dt`` seconds ahead; add region births.

    The cardinality prediction includes the Poisson birth of the region components and of
    the uniform birth intensity that :func:`update_state` evaluates per cell.
    """
    mc = cfg.model
    mixture = predict(state.mixture, dt, mc.p_survival, mc.sigma_accel, mc.tau_rate,
                      mc.tau_extent)
    next_label = state.next_label
    birth_mean = birth_intensity(cfg, dt)
    if len(cfg.birth.regions):
        regions = region_births(cfg, next_label)
        next_label += len(regions)
        birth_mean += float(np.sum(regions.w))
        mixture = Mixture.concat([mixture, regions])
    p_s = mc.p_survival ** dt
    log_card = state.log_card
    if len(log_card) != mc.n_max + 1:                 # N_max changed while running
        log_card = resize_cardinality(log_card, mc.n_max)
    log_card = predict_cardinality(log_card, p_s, birth_mean)
    return replace(state, mixture=mixture, log_card=log_card, next_label=next_label, dt=dt)


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
    inverses = inv2(np.concatenate([G, mix.P[best][:, :2, :2]
                                    + mix.expected_extent(best) + R]))
    return inverses[:n], {
        'centre': mix.m[best][:, :2],
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
    # beta as rate_shape / expected_rate once, in Python: the same double as dividing
    # every alpha by expected_rate
    alpha, beta = np.full(k, float(b.rate_shape)), np.full(k, b.rate_shape / b.expected_rate)
    return Mixture(np.full(k, 1.0), alpha, beta, m, P0.repeat(k, axis=0), np.full(k, float(b.dof)),
                   V0.repeat(k, axis=0), np.zeros(k, dtype=np.int64))


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
                 centroid_offset: np.ndarray | None = None, pair_p_d=None,
                 clutter_log_density: np.ndarray | None = None,
                 shadowed: np.ndarray | None = None, no_birth=None):
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
        Area (m^2) births, and clutter unless ``clutter_log_density`` is given, are spread
        over; ``model.surveillance_area`` if omitted.
    visibility : (n,) array, optional
        Visible fraction of each component, carried into the estimates (a label's is its
        heaviest component's).
    centroid_offset : (n, 2) array, optional
        Expected offset of each component's visible centroid (see ``update_pairs``).
    pair_p_d : callable, optional
        ``pair_p_d(mix, comp, m_updated, P_updated) -> (k,)`` p_D of each (component,
        cell) pair at its updated position; by default ``p_d[comp]``. ``p_d`` itself is
        still what the missed-detection factor uses.
    clutter_log_density : (m,) array, optional
        ``log c(z)`` of each detection, the clutter spatial density there (1/m^2); uniform
        over ``clutter_area`` if omitted.
    shadowed : (n,) bool array, optional
        Components whose own extent lies wholly in shadow (the scan-shadow model's plain
        interval). With ``detection.hold_hidden``, those of confirmed labels take p_D 0 in
        their missed-detection factor unless a cell lies on their predicted outline
        (:func:`_held_p_d`); in CPHD mode one object's worth of a label so held and
        wholly out of sight is kept out of the update (:func:`_out_of_sight`).
    no_birth : callable, optional
        ``no_birth(births) -> (j,) bool``: which of the birth hypotheses ``births`` (the
        birth posteriors of the cells of at least ``birth.min_points`` returns that no
        existing component is paired with, a :class:`ggiw.PairUpdate`) are no object the
        sensor could see (the scan-shadow model's :func:`sensing.shadow.sparse_births`).
        Those births take p_D 0; a cell of several returns left with no explanation is
        then clutter return by return, as for ``birth.min_points``.

    Returns
    -------
    state : FilterState
    estimates : Estimates
        The confirmed labels, with the thin pieces of one contour reported as one object
        (:func:`identity.group_segments`).
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
    if not np.all(np.isfinite(points)):
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
    stats = cell_stats(points, pset.cells, clutter_log_density)
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
    born_rows = np.arange(n_comp, n_comp + n_cells)            # the birth row of each cell
    upd_all = update_pairs(both, np.concatenate([comp, born_rows]), stats,
                           np.concatenate([cell, bcell]), mc.rho, R,
                           _pad(rate_scale, n_cells, 1.0), _pad(hidden, n_cells, 0.0),
                           _pad(centroid_offset, n_cells, 0.0))
    k = len(comp)
    pair_lik, birth_lik = upd_all.log_lik[:k], upd_all.log_lik[k:]
    p_d_pair = (p_d[comp] if pair_p_d is None
                else pair_p_d(mix, comp, upd_all.m[:k], upd_all.P[:k]))
    keep = p_d_pair > 0.0
    pair_rows = None                           # rows of upd_all holding the pairs kept
    if not np.all(keep):
        pair_rows = keep.nonzero()[0]
        comp, cell, p_d_pair, pair_lik = comp[keep], cell[keep], p_d_pair[keep], pair_lik[keep]
    diag.pairs = len(comp)
    held = None
    if shadowed is not None and cfg.detection.hold_hidden:
        p_d, held = _held_p_d(state, cfg, p_d, shadowed, comp, cell, stats.mean, R)
        diag.held = int(np.count_nonzero(held))
    log_pd0 = np.log(cfg.detection.p_d0)

    log_g = np.full((n_comp + 1, n_cells), -np.inf)
    log_g[comp, cell] = np.log(p_d_pair) + pair_lik
    born_ok = stats.n >= cfg.birth.min_points
    if no_birth is not None:
        # births the sensor could not have seen, on cells no component is paired with:
        # beside a track a few returns are as likely its own (a walker's leg), and
        # refusing the birth there changed which of a walker's legs kept a label on the
        # recordings
        free = born_ok.copy()
        free[cell] = False
        if np.any(free):
            rows = free.nonzero()[0]
            refused = rows[no_birth(upd_all.take(k + rows))]
            diag.sparse_births = len(refused)
            born_ok[refused] = False
    log_g[n_comp, :] = np.where(born_ok, log_pd0 + birth_lik, NEG_INF)
    lonely = None
    if cfg.birth.min_points > 2 or diag.sparse_births:
        # a cell of several returns too few to be born from, that no object explains, is
        # clutter return by return (clutter alone would make every partition holding it
        # impossible, and the cardinality NaN from then on)
        lonely = (stats.n > 1) & ~np.isfinite(log_g).any(axis=0)
        if not np.any(lonely):
            lonely = None
    partitions = pset.partitions
    if lonely is not None:
        partitions = _distinct_with_lonely(partitions, pset.cells, stats.n, lonely,
                                           len(points))
    mu_b = birth_intensity(cfg, state.dt)
    with np.errstate(divide='ignore'):
        log_w = np.concatenate([np.log(mix.w), [np.log(mu_b)]])
        log_qd = np.concatenate([log_miss_factor(mix, p_d, rate_scale),
                                 [_birth_log_miss_factor(cfg)]])
    cell_log_c = -stats.n * np.log(area) if stats.log_c is None else stats.log_c
    if mc.mode == 'cphd':
        # the clutter pmf up to every detection: no partition can take more as clutter
        # (cphd_update reads the entries up to the most a partition takes)
        clutter_pmf = _clutter_log_pmf(mc.clutter_rate, len(points) + 1)
        log_card, apart = state.log_card, None
        if diag.held:
            # labels wholly out of sight: one object's worth of each kept apart (below)
            apart = _out_of_sight(mix, held, comp)
            if apart is not None:
                rows, w_apart = apart
                total_apart = float(np.sum(w_apart))
                with np.errstate(divide='ignore'):
                    log_w[rows] = np.log(np.maximum(mix.w[rows] - w_apart, 0.0))
                log_card = thin_cardinality(log_card, total_apart)
        out = cphd_update(log_w, log_qd, log_g, cell_log_c, stats.n, partitions,
                          log_card, clutter_pmf, lonely)
        if apart is not None:
            log_w_missed = out.log_w_missed.copy()
            log_w_missed[rows] = np.log(np.exp(log_w_missed[rows]) + w_apart)
            out = replace(out, log_w_missed=log_w_missed,
                         log_card=add_cardinality(out.log_card, total_apart))
    else:
        out = phd_update(log_w, log_qd, log_g, cell_log_c, stats.n, partitions,
                         mc.clutter_rate, mc.n_max, lonely)
    # no partition explains the scan (more objects than model.n_max in every one): the
    # prediction stands, and the diagnostics say so
    diag.unexplained = int(not out.possible)

    # posterior mixture: missed components, (component, cell) updates, births
    prune = cfg.reduction.prune_weight
    w_missed = np.exp(out.log_w_missed[:n_comp])
    w_det = np.exp(out.log_w_detected[comp, cell])
    sel = (w_det >= prune).nonzero()[0]
    w_birth = np.exp(out.log_w_detected[n_comp, :])
    bsel = (w_birth >= cfg.birth.min_weight).nonzero()[0]
    # which label explains each cell best is asked only where a birth may take it
    claims = _cell_claims(mix, comp, cell, w_det, n_cells) if len(bsel) else (None, None)
    born, next_label = _label_births(pset, bsel, state.next_label, *claims, w_birth)
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
    if visibility is not None and n_comp:
        # each label's visible fraction is its heaviest predicted component's
        order, is_head, _ = mix.by_label()
        heads = order[is_head]
        vis_of = dict(zip(mix.label[heads].tolist(), visibility[heads].tolist()))

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

    new_state = replace(state, mixture=reduced, log_card=out.log_card, next_label=next_label)
    candidates = extract(new_state, cfg, n_det, vis_of)
    new_state, candidates, diag.relabelled = relabel_jumps(state, new_state, candidates, cfg)
    new_state, candidates, record, diag.handed_over = hand_over(state, new_state, candidates,
                                                                cfg)
    new_state = record_reports(record, new_state, candidates)
    joined = forming = NO_LABELS
    if cfg.reduction.pair_scans:
        new_state, candidates, joined, forming = join_pairs(new_state, candidates, cfg)
        diag.joined_labels = len(joined)
    # report a label once confirmed (M of N); a part never shown waits while its pair forms
    confirmed = new_state.confirmed_rows(cfg.extraction)
    if len(forming):
        confirmed &= ~(find_sorted(np.sort(forming), candidates.label)[1]
                       & ~find_sorted(state.shown, candidates.label)[1])
    shown = candidates if np.all(confirmed) else candidates.take(confirmed)
    new_state = remember_shown(state, new_state, shown, cfg.extraction.handover_time, joined)
    # the filter's own estimates are what the shown record keeps; the report groups the
    # pieces of one contour
    shown, diag.grouped = group_segments(shown, new_state.reported_scans[confirmed],
                                         cfg.extraction.group_gap,
                                         cfg.extraction.group_speed)
    return new_state, shown, diag


def _distinct_with_lonely(partitions, cells, size, lonely, m: int) -> list:
    """
    ``partitions`` without those that repeat an earlier one once every ``lonely`` cell is
    taken as its returns one by one, as the update takes it.

    Notes
    -----
    A lonely cell (several returns no object and no birth explains) is evaluated as that
    many clutter returns, and so is the same returns' split into lone returns that
    ``partition.split_small`` adds, or into a smaller lonely cell and lone returns that a
    finer distance threshold gives: such partitions are one hypothesis, and kept all it
    would count several times. In the ``clutter`` scene, with births on the clutter by
    the scanner refused, 352 of 600 scans had such twins (seeds 10-14).

    A partition is written as its parts: a return ``z`` (a singleton, or a lonely cell's
    member) as code ``z``, any other cell ``c`` as ``m + c``. Each code gets a 64-bit
    value (splitmix64) and a partition the wrapping sum of its parts' values, all in a few
    array operations; only partitions whose sums agree are compared code by code (sorted),
    so a collision of sums can never drop a partition that differs.
    """
    sizes = np.fromiter(map(len, partitions), dtype=np.int64, count=len(partitions))
    if len(partitions) < 2 or not np.all(sizes):
        return partitions
    n_cells = len(cells)
    member_sum = np.add.reduceat(_mix64(np.concatenate(cells)),          # size: returns
                                 np.concatenate([[0], np.cumsum(size)[:-1]]))  # per cell
    as_returns = lonely | (size == 1)
    cell_val = np.where(as_returns, member_sum, _mix64(m + np.arange(n_cells)))
    flat = np.concatenate(partitions)
    total = np.add.reduceat(cell_val[flat], np.concatenate([[0], np.cumsum(sizes)[:-1]]))
    _, inverse, counts = np.unique(total, return_inverse=True, return_counts=True)
    if counts.max() == 1:
        return partitions
    keep, seen = [], set()
    for i, p in enumerate(partitions):
        if counts[inverse[i]] == 1:
            keep.append(p)
            continue
        parts = [cells[c] if as_returns[c] else np.array([m + c]) for c in p.tolist()]
        key = np.sort(np.concatenate(parts)).tobytes()
        if key not in seen:
            seen.add(key)
            keep.append(p)
    return keep


def _mix64(x: np.ndarray) -> np.ndarray:
    """splitmix64 of integers ``x``: well-spread 64-bit values, wrapping arithmetic."""
    z = np.asarray(x, dtype=np.uint64) + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


HOLD_OUTLINE = 1.0    # squared distance within which a cell is on a held component's outline


def _held_p_d(state: FilterState, cfg: TrackerConfig, p_d: np.ndarray, shadowed: np.ndarray,
              comp: np.ndarray, cell: np.ndarray, cell_mean: np.ndarray, R: np.ndarray):
    """
    ``p_d`` with 0 for the components held from a miss, and which those are (a mask):
    the ``shadowed`` ones of confirmed labels that no cell lies on.

    Notes
    -----
    A component wholly in shadow gets its p_D from its interval widened by the position
    uncertainty, which reaches past the shadow as a hidden track coasts: a miss there is
    the prediction's spread, not a sign that the object is gone, and counting it scan
    after scan retired tracks the scan-shadow model is there to keep (a crowd's walkers).
    A label not yet confirmed still fades so: a spurious track beside a person would
    otherwise live on in its shadow.

    A cell lies on a component when it is one of its pairs (``comp``, ``cell``; centroids
    ``cell_mean``) and its centroid is within the component's predicted outline, the
    expected extent grown by the position covariance and the sensor noise (squared
    distance ``HOLD_OUTLINE``). There the object may be in view after all, as when a
    track lags behind its person and its own returns shadow the prediction, and the
    miss stands: held, the missed copy would keep all its weight beside the detected
    ones, and the label split (the leg_tracker demo). A cell only in the gate, beside
    the outline, is most often the occluder in front of a hidden object, and holds
    nothing back.
    """
    if not np.any(shadowed) or not len(state.reported):
        return p_d, np.zeros(len(p_d), dtype=bool)
    mix = state.mixture
    confirmed = state.reported[state.confirmed_rows(cfg.extraction)]
    held = shadowed & find_sorted(confirmed, mix.label)[1]
    rows = held[comp].nonzero()[0]                     # the held components' pairs
    if len(rows):
        c = comp[rows]
        e = cell_mean[cell[rows]] - mix.m[c, :2]
        S = mix.expected_extent(c) + mix.P[c, :2, :2] + R
        held[c[quad_form2(e, inv2(S)) <= HOLD_OUTLINE]] = False
    return np.where(held, 0.0, p_d), held


def _out_of_sight(mix: Mixture, held: np.ndarray, comp: np.ndarray):
    """
    The held components of labels wholly out of sight (held, and no component of the
    label paired with a cell), as ``(rows, w_apart)``: the weight of each kept out of the
    CPHD update, one object's worth per label (``min(w, 1)`` of the label's held weight
    ``w``, shared among its held components as they hold it); None if there are none.

    Notes
    -----
    The CPHD scales every missed weight by one factor that its cardinality sets, a held
    component's too, so a hidden walker's label faded wherever the cardinality counted
    fewer objects than the labels' weights: in ``crowd20`` a walker's label went from
    2.18 to 0.27 in 14 scans, held throughout, its estimate within 0.14 m of the walker.
    No return can tell such a label anything. So one object's worth of it is taken out
    of the update, as an object the scan cannot see, the cardinality thinned by it
    first (:func:`cphd.thin_cardinality`) and given it back after
    (:func:`cphd.add_cardinality`). The rest of it (a label's excess over one, the
    weight gathered from both legs, say) stays in the update to fade as before, and so
    does every label with a component paired (part of it in view): taking whole weights
    out, or those of labels in part in view, kept second copies of people on the
    recordings (``doc/history.md``). In PHD mode a p_D of 0 keeps the missed weight
    anyway.
    """
    rows = (held & ~find_sorted(np.unique(mix.label[comp]), mix.label)[1]).nonzero()[0]
    if not len(rows):
        return None
    _, group = np.unique(mix.label[rows], return_inverse=True)
    w = mix.w[rows]
    return rows, w * np.minimum(1.0, 1.0 / np.bincount(group, weights=w)[group])


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
    X = mix.expected_extent()
    limit2 = cfg.reduction.max_semi_axis ** 2
    pos_var = np.maximum(mix.P[:, 0, 0], mix.P[:, 1, 1])
    coasted = pos_var > cfg.reduction.max_position_std ** 2
    # the larger eigenvalue of an SPD matrix is at most its trace: where every trace is
    # clearly under the limit (most scans) no eigenvalue is taken (the margin covers the
    # closed form's rounding)
    if not len(X):
        return coasted
    if float(np.max(X[:, 0, 0] + X[:, 1, 1])) * (1.0 + 1e-9) < limit2:
        return coasted
    major2, _ = eig2(X)
    return (major2 > limit2) | coasted


def gate_threshold(cfg: TrackerConfig) -> float:
    """Squared Mahalanobis gate of (component, cell) pairs (chi-square, 2 dof)."""
    return _chi2_2dof_ppf(cfg.partition.gate_probability)


@lru_cache(maxsize=64)                 # asked for twice a scan with the same probability
def _chi2_2dof_ppf(p: float) -> float:
    """``chi2.ppf(p, 2) = -2 log(1 - p)``; ``inf`` (no gate) at ``p = 1``."""
    if p >= 1.0:
        return float(np.inf)           # log1p(-1) would warn of a division by zero
    return float(-2.0 * np.log1p(-p))



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
    # a handful of labels and pairs: Python sums, in the order bincount would add them
    rank = inv.tolist()
    detected, missed = [0.0] * len(labels), [0.0] * len(labels)
    for r, w in zip(rank, w_missed.tolist()):
        missed[r] += w
    heaviest = {}                                      # label rank -> its heaviest pair
    keys = weight_key(w_det).tolist()                  # ties but for the last bits: first
    for j, (c, w) in enumerate(zip(comp.tolist(), w_det.tolist())):
        r = rank[c]
        detected[r] += w
        if r not in heaviest or keys[j] > keys[heaviest[r]]:
            heaviest[r] = j
    lab, size, cells = labels.tolist(), stats.n.tolist(), cell.tolist()
    return {lab[r]: size[cells[j]] for r, j in sorted(heaviest.items())
            if detected[r] > missed[r]}


def _spread_inv(mix: Mixture, idx) -> np.ndarray:
    """Inverse of position covariance plus expected extent of components ``idx``: the
    metric in which a label's members are near their head (splitting, fusion)."""
    return inv2(mix.P[idx][:, :2, :2] + mix.expected_extent(idx))


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
    # only labels light enough to pair with the lightest other one can take part (the two
    # lightest by a Python sort: a handful of labels)
    wl = weight.tolist()
    low, second = sorted(wl)[:2]
    cand = [i for i, x in enumerate(wl) if x + (second if x == low else low) <= fuse_weight]
    if len(cand) < 2:
        return mix, 0
    cand = np.array(cand, dtype=np.int64)
    heads = order[is_head][cand]
    c = mix.m[heads][:, :2]
    inv_spread = _spread_inv(mix, heads)
    e = c[None, :, :] - c[:, None, :]                  # e[i, j] = c_j - c_i
    d2 = np.einsum('ijk,ikl,ijl->ij', e, inv_spread, e)    # in head i's metric
    close = (np.maximum(d2, d2.T) <= merge_distance)
    np.fill_diagonal(close, False)
    if not np.any(close):
        return mix, 0
    scans = np.zeros(len(cand), dtype=np.int64)
    if reported is not None and len(reported):
        at, ok = find_sorted(labels, reported)
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
    return replace(mix, label=label), fused


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
    if np.all(is_head):
        return mix, next_label                         # one component a label (most scans)
    heads = order[is_head]
    pos = mix.m[:, :2]
    e = pos[order] - pos[heads[group]]
    d2 = np.einsum('ki,kij,kj->k', e, _spread_inv(mix, heads)[group], e)
    far = np.zeros(len(mix), dtype=bool)
    far[order] = (d2 > merge_distance) & ~is_head
    if not np.any(far):
        return mix, next_label
    heavy = far & (mix.w >= split_weight)
    label = mix.label.copy()
    # fresh labels in order of weight, as the objects they stand for are found
    new = heavy.nonzero()[0]
    new = new[(-weight_key(mix.w[new])).argsort(kind='stable')]
    label[new] = next_label + np.arange(len(new))
    keep = ~(far & ~heavy)
    return replace(mix, label=label).take(keep), next_label + len(new)


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
    ex = cfg.extraction
    # the labels heaviest first (weight_key; ties by label), a handful: a Python sort
    keys = (-weight_key(weight)).tolist()
    order = sorted(range(len(keys)), key=keys.__getitem__)
    w = weight.tolist()
    if cfg.model.mode == 'cphd':
        chosen = order[:int(state.log_card.argmax())]
    else:
        chosen = [i for i in order if w[i] > ex.phd_threshold]
    # in label order (the labels ascend)
    chosen = sorted(i for i in chosen if w[i] >= ex.min_existence)
    if not chosen:
        return Estimates.empty()
    at = np.array(chosen, dtype=np.int64)
    best, lab_w, chosen = heads[at], weight[at], labels[at]
    n_det = n_det or {}
    visibility = visibility or {}
    reported = chosen.tolist()
    return Estimates(
        label=chosen,
        existence=np.minimum(np.maximum(lab_w, 0.0), 1.0),
        m=mix.m[best],
        P=mix.P[best],
        X=mix.expected_extent(best),
        rate=mix.expected_rate()[best],
        num_detections=np.array([n_det.get(x, 0) for x in reported], dtype=np.int64),
        visibility=np.array([visibility.get(x, 1.0) for x in reported]),
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
        pd = np.full(len(pred.mixture), float(cfg.detection.p_d0 if p_d is None else p_d))
    return update_state(pred, points, pd, cfg, clutter_area=clutter_area)
