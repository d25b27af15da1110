"""
Measurement partitioning: distance, sub- and prediction partitioning, with caps.

A partition is returned as a label array over the detections; :class:`PartitionSet`
turns a list of them into distinct cells (index arrays) and partitions as lists of cell
indices, so that each cell's update is computed once however many partitions hold it.

Notes
-----
Granström, Lundquist & Orguner, IEEE TAES 48(4), 2012, section IV. Distance partitioning
for every distinct threshold in ``[d_min, d_max]`` equals cutting the single-linkage
dendrogram at each merge height in that range; the merges are the edges of the minimum
spanning tree of the radius-``d_max`` graph, so all partitions come from one MST.

"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .distance import distance_partitions
from .ggiw import centre_distance2
from .kmeans import kmeans_pp


@dataclass
class PartitionSet:
    """
    Distinct cells and the partitions built from them.

    Attributes
    ----------
    cells : list of int arrays
        Sorted detection indices of each distinct cell.
    partitions : list of int arrays
        Each partition as indices into ``cells``; together they cover every detection once.
    capped_partitions, capped_cells : int
        How many partitions or cells the caps dropped.

    """

    cells: list = field(default_factory=list)
    partitions: list = field(default_factory=list)
    capped_partitions: int = 0
    capped_cells: int = 0
    _index: dict = field(default_factory=dict)
    _seen: set = field(default_factory=set)

    def add(self, labels: np.ndarray, max_partitions: int, max_cells: int) -> bool:
        """
        Add the partition given by ``labels`` unless it is a duplicate or over a cap.

        Once ``max_partitions`` are held, every further partition counts as capped without
        being examined (a duplicate among them is counted too): under load the cap is
        what bounds the time spent here.
        """
        if len(self.partitions) >= max_partitions:
            self.capped_partitions += 1
            return False
        return self._commit([[g, self._index.get(g.tobytes())] for g in _groups(labels)],
                            max_cells)

    def add_nested(self, partitions: list, max_partitions: int, max_cells: int) -> None:
        """
        Add a sequence of partitions, each coarser than the one before, as :meth:`add` would.

        A label must be the smallest detection index of its cell (as
        :func:`distance_partitions` gives). From one partition to the next only the cells
        that grew are new; the others keep their ids, so the work per partition is the
        detections that moved and the changed cells, not every cell again.
        """
        current = {}                                  # label -> [members, cell id or None]
        prev = None
        for labels in partitions:
            if prev is None:
                current = {r: [g, None] for r, g in zip(*_groups(labels, with_labels=True))}
                fresh = list(current)
            else:
                moved = labels != prev
                for r in set(prev[moved].tolist()):
                    del current[r]                    # absorbed into a smaller label
                fresh = sorted(set(labels[moved].tolist()))
                for r in fresh:
                    current[r] = [(labels == r).nonzero()[0], None]
            prev = labels
            for r in fresh:
                entry = current[r]
                entry[1] = self._index.get(entry[0].tobytes())
            if len(self.partitions) >= max_partitions:
                self.capped_partitions += 1
                continue
            self._commit([current[r] for r in sorted(current)], max_cells)

    def add_splits(self, finest: np.ndarray, split_small: int, max_partitions: int,
                   max_cells: int) -> None:
        """
        For each cell of the finest distance partition ``finest`` (labels as
        :func:`distance_partitions` gives them) with 2 up to ``split_small`` detections,
        that partition with the cell's detections as lone returns, as :meth:`add` would
        add its label array (added last: under the partition cap the others come first).

        Notes
        -----
        Returns closer together than ``d_min`` share a cell in every distance partition,
        and clutter comes one return at a time, so without this the update could only
        explain such a pair as an object, whatever the clutter density: in ``clutter``
        two spurious returns within centimetres of each other were born as a track of
        weight 1.00 in every scan they fell so, at 0.3 m from the scanner as at 3.5 m.
        With the pair also held as two single returns, the update weighs an object there
        against two clutter returns (and a track may still take either return alone).
        """
        counts = np.bincount(finest, minlength=len(finest))
        small = (counts >= 2) & (counts <= split_small)
        if not small.any():
            return
        # the finest partition's cells once (the entries are shared, so a cell one variant
        # adds is known to the next); each variant is them with one cell's returns alone
        # at the end, the order add would give that label array
        base = [[g, self._index.get(g.tobytes())] for g in _groups(finest)]
        for k, (g, _) in enumerate(base):
            if not small[g[0]]:              # a cell's label is its smallest detection
                continue
            if len(self.partitions) >= max_partitions:
                self.capped_partitions += 1
                continue
            alone = [[g[i:i + 1], self._index.get(g[i:i + 1].tobytes())]
                     for i in range(len(g))]
            self._commit(base[:k] + base[k + 1:] + alone, max_cells)

    def _commit(self, entries: list, max_cells: int) -> bool:
        """
        Add the partition whose cells are ``entries`` (``[members, id]`` each, ``id`` None
        for a cell not held yet) unless it is a duplicate or its new cells would pass the
        cell cap; the new cells' ids are written into their entries. The first partition
        is always taken: without one the scan could not update the tracks at all.
        """
        new = [e for e in entries if e[1] is None]
        if not new and tuple(sorted(e[1] for e in entries)) in self._seen:
            return False
        if len(self.cells) + len(new) > max_cells and self.partitions:
            self.capped_cells += len(new)
            return False
        for e in new:
            e[1] = len(self.cells)
            self.cells.append(e[0])
            self._index[e[0].tobytes()] = e[1]
        ids = [e[1] for e in entries]
        self._seen.add(tuple(sorted(ids)))
        self.partitions.append(np.array(ids, dtype=np.int64))
        return True


def _groups(labels: np.ndarray, with_labels: bool = False):
    """
    The cells of a label array: index arrays in ascending label order, each ascending;
    with ``with_labels``, ``(labels, cells)``, each cell's label as a Python int.
    """
    order = labels.argsort(kind='stable')
    lab = labels[order]
    cuts = [0, *[i + 1 for i in (lab[1:] != lab[:-1]).nonzero()[0].tolist()], len(order)]
    cells = [order[a:b] for a, b in zip(cuts[:-1], cuts[1:])]
    if not with_labels:
        return cells
    lab = lab.tolist()
    return [lab[a] for a in cuts[:-1]], cells


def _sums_by(labels: np.ndarray, points: np.ndarray, n: int) -> np.ndarray:
    """(n, 2) sums of the points of each label ``0..n-1``."""
    out = np.empty((n, 2))
    out[:, 0] = np.bincount(labels, weights=points[:, 0], minlength=n)
    out[:, 1] = np.bincount(labels, weights=points[:, 1], minlength=n)
    return out


MIN_RATE = 1e-9


def expected_object_counts(n_points: np.ndarray, rate: np.ndarray, k_max: int) -> np.ndarray:
    """
    Most likely number of objects ``k`` behind each cell's ``n_points`` detections, each
    object at ``rate`` detections per scan.

    Notes
    -----
    ``argmax_k Poisson(n; k rate)`` over ``k = 1..k_max`` (Granström et al. 2012, IV-C),
    for every cell at once.
    """
    k = np.arange(1, k_max + 1)[None, :]
    mean = k * np.maximum(rate, MIN_RATE)[:, None]
    log_p = n_points[:, None] * np.log(mean) - mean
    return log_p.argmax(axis=1) + 1


def build_partitions(points: np.ndarray, cfg, predicted=None, seed: int = 0) -> PartitionSet:
    """
    All partitions of one scan's detections.

    Parameters
    ----------
    points : (m, 2) array
        Detections.
    cfg : PartitionConfig
        Thresholds, caps and switches.
    predicted : dict, optional
        Confident predicted objects for sub- and prediction partitioning: ``centre``
        (k, 2), ``gate_inv`` (k, 2, 2) inverse gate covariances, ``gate`` threshold,
        ``rate`` (k,) expected detections per scan.
    seed : int
        Seed of k-means++ (deterministic results).

    """
    pset = PartitionSet()
    m = len(points)
    if m == 0:
        pset.partitions.append(np.zeros(0, dtype=np.int64))
        return pset
    dist, dropped = distance_partitions(points, cfg.d_min, cfg.d_max, cfg.max_partitions)
    pset.capped_partitions += dropped
    middle = dist[len(dist) // 2]                      # a middle distance partition
    confident = predicted is not None and len(predicted['centre']) > 0
    use_pred = cfg.prediction_partition and confident
    big = _big_cells(points, middle) if cfg.sub_partition and confident else None
    # the gate distances of the detections (prediction partitioning) and of the big
    # cells' centroids (sub-partitioning) in one evaluation
    d2_points = d2_big = None
    if use_pred or big is not None:
        rows = [points] if use_pred else []
        if big is not None:
            rows.append(big[2])
        d2 = _gate_d2(rows[0] if len(rows) == 1 else np.concatenate(rows), predicted)
        d2_points, d2_big = (d2[:m], d2[m:]) if use_pred else (None, d2)
    # prediction partitioning first: under a cap it is the most informative one
    if use_pred:
        pset.add(prediction_partition(points, predicted, middle, d2_points),
                 cfg.max_partitions, cfg.max_cells)
    pset.add_nested(dist, cfg.max_partitions, cfg.max_cells)
    if big is not None:
        _sub_partitions(points, pset, middle, big, d2_big, predicted, cfg, seed)
    if cfg.split_small >= 2:
        pset.add_splits(dist[0], cfg.split_small, cfg.max_partitions, cfg.max_cells)
    return pset


def _gate_d2(z: np.ndarray, predicted) -> np.ndarray:
    """(j, k) squared distances of points ``z`` (j, 2) to the confident predictions, each
    in its own gate metric."""
    return centre_distance2(predicted['centre'], predicted['gate_inv'], z).T


def _big_cells(points: np.ndarray, labels: np.ndarray):
    """
    ``(labels, counts, centroids)`` of the cells of ``labels`` (a distance partition:
    labels are detection indices) with at least 4 detections, the ones sub-partitioning
    may split; None if there is none.
    """
    m = len(points)
    counts_all = np.bincount(labels, minlength=m)    # not unique / add.at
    big = (counts_all >= 4).nonzero()[0]
    if not len(big):
        return None
    counts = counts_all[big]
    return big, counts, _sums_by(labels, points, m)[big] / counts[:, None]


def prediction_partition(points, predicted, fallback_labels, d2=None):
    """
    Detections in a confident object's gate go to the nearest such object.

    The others keep their cells of ``fallback_labels`` (a middle distance partition).
    ``d2`` (m, k) are the detections' gate distances if already computed.
    """
    if d2 is None:
        d2 = _gate_d2(points, predicted)
    best = d2.argmin(axis=1)
    inside = d2[np.arange(len(points)), best] < predicted['gate']
    labels = len(predicted['centre']) + np.asarray(fallback_labels, dtype=np.int64)
    labels[inside] = best[inside]
    return labels


def _sub_partitions(points, pset, base, big, d2, predicted, cfg, seed):
    """
    Split cells that likely hold several objects, one new partition per split cell.

    ``base`` is the middle distance partition, ``big`` its cells of at least 4 detections
    (:func:`_big_cells`) and ``d2`` their centroids' gate distances to the predictions.
    """
    labels, counts, _ = big
    centre = predicted['centre']
    near = d2 < predicted['gate']
    cand = near.any(axis=1).nonzero()[0]
    if not len(cand):
        return
    nc_all = near[cand]
    # objects whose gate holds the cell, and the count its size suggests at their mean rate
    k_pred = nc_all.sum(axis=1)
    rate = (nc_all @ predicted['rate']) / k_pred
    k_rate = expected_object_counts(counts[cand], rate, cfg.max_sub_objects)
    k_all = np.minimum(np.minimum(np.maximum(k_pred, k_rate), cfg.max_sub_objects),
                       counts[cand])
    for row in (k_all >= 2).nonzero()[0]:
        if len(pset.partitions) >= cfg.max_partitions:
            pset.capped_partitions += 1               # no room: not worth a k-means
            continue
        c = cand[row]
        k = int(k_all[row])
        idx = (base == labels[c]).nonzero()[0]
        init = centre[nc_all[row]][:k] if k_pred[row] >= k else None
        sub = kmeans_pp(points[idx], k, seed=seed, init=init)
        new = base.copy()
        new[idx] = base.max() + 1 + sub
        pset.add(new, cfg.max_partitions, cfg.max_cells)


def distinct_with_lonely(partitions, cells, size, lonely, m: int) -> list:
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
    if len(partitions) < 2 or not sizes.all():
        return partitions
    n_cells = len(cells)
    member_sum = np.add.reduceat(mix64(np.concatenate(cells)),          # size: returns
                                 np.concatenate([[0], np.cumsum(size)[:-1]]))  # per cell
    as_returns = lonely | (size == 1)
    cell_val = np.where(as_returns, member_sum, mix64(m + np.arange(n_cells)))
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


def mix64(x: np.ndarray) -> np.ndarray:
    """splitmix64 of integers ``x``: well-spread 64-bit values, wrapping arithmetic."""
    z = np.asarray(x, dtype=np.uint64) + np.uint64(0x9E3779B97F4A7C15)
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))
