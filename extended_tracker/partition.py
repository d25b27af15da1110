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
import threading

import numpy as np
from scipy.cluster.hierarchy import linkage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import minimum_spanning_tree
from scipy.spatial import cKDTree, Delaunay, QhullError
from scipy.spatial.distance import pdist

from .ggiw import centre_distance2


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
        if not np.any(small):
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


LINKAGE_MAX = 1150      # up to this many detections: scipy's single linkage on all pairs


def _merges(points: np.ndarray, d_max: float):
    """
    The single-linkage merges up to height ``d_max``, in ascending height.

    Returns
    -------
    a, b : lists of k ints
        The smallest detection index of each of the two clusters joined, the smaller
        first (``a[i] < b[i]``).
    height : (k,) array
        The merge heights (the minimum spanning forest's edge lengths).

    Notes
    -----
    Up to ``LINKAGE_MAX`` detections this is scipy's single linkage over all pairwise
    distances (an O(n^2) MST in C: 1.2 ms for 600 returns of a 4000-beam scan, 3.1 ms for
    1000, where the path below took 2.5 and 3.9 ms); beyond it, scipy's sparse MST over
    the Delaunay edges no longer than ``d_max`` (:func:`_mst_edges`: 5.3 ms for 1500
    returns against linkage's 6.9, 6.3 for 1700 against 10.0), whose merges are read by a
    union-find pass. Both give the same merge heights, so the same partitions.
    """
    n = len(points)
    if n < 2:
        return [], [], np.zeros(0)
    if n <= LINKAGE_MAX:
        z = linkage(pdist(points), method='single')
        k = int(z[:, 2].searchsorted(d_max, side='right'))
        pair = z[:k, :2].astype(np.int64).tolist()
        rep = list(range(n)) + [0] * k                # a cluster's smallest detection index
        a, b = [0] * k, [0] * k
        for i, (u, v) in enumerate(pair):
            ru, rv = rep[u], rep[v]
            if ru < rv:
                a[i], b[i] = ru, rv
                rep[n + i] = ru
            else:
                a[i], b[i] = rv, ru
                rep[n + i] = rv
        return a, b, z[:k, 2].copy()
    rows, cols, length = _mst_edges(points, d_max)
    order = np.argsort(length, kind='stable')
    parent = list(range(n))
    a, b = [], []
    for u, v in zip(rows[order].tolist(), cols[order].tolist()):
        ru, rv = find_root(parent, u), find_root(parent, v)
        lo, hi = (ru, rv) if ru < rv else (rv, ru)
        a.append(lo)
        b.append(hi)
        parent[hi] = lo
    return a, b, length[order]


def _mst_edges(points: np.ndarray, d_max: float):
    """
    Edges (i, j, length) of the minimum spanning forest of the radius-``d_max`` graph.

    Notes
    -----
    The Delaunay triangulation's edges hold the Euclidean minimum spanning tree, so its
    edges no longer than ``d_max`` hold the forest: at most ``3n`` edges, whatever the
    density. The pairs within ``d_max`` are listed only where qhull cannot triangulate
    (all returns on one line). Past ``LINKAGE_MAX`` returns a scan comes from a
    high-resolution scanner and is dense along its surfaces (4000 beams: 6 mm apart at
    5 m, hundreds of returns within ``d_max`` of each), where listing the pairs, or even
    counting them to choose, costs more than the triangulation (a 12 700-return scan
    listed 12 million pairs: 0.7 s and 1 GB).
    """
    n = len(points)
    pairs = _delaunay_pairs(points)
    if pairs is None:                     # all on a line: no triangulation
        pairs = cKDTree(points).query_pairs(d_max, output_type='ndarray')
        if not len(pairs):
            return np.zeros(0, int), np.zeros(0, int), np.zeros(0)
    d = np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1)
    near = d <= d_max
    pairs, d = pairs[near], d[near]
    # zero-length edges (repeated points) would vanish from a sparse matrix: lift them
    d = np.maximum(d, 1e-12)
    graph = coo_matrix((d, (pairs[:, 0], pairs[:, 1])), shape=(n, n)).tocsr()
    mst = minimum_spanning_tree(graph).tocoo()
    return mst.row, mst.col, mst.data


def _delaunay_pairs(points: np.ndarray):
    """
    Edges ``(i, j)``, ``i < j``, of the Delaunay triangulation, which contain the
    Euclidean minimum spanning tree, each once, in ascending order; duplicate points (left
    out of the triangulation) are joined to the vertex they coincide with. ``None`` where
    qhull cannot triangulate (all points on a line).
    """
    try:
        tri = Delaunay(points)
    except QhullError:
        return None
    s = tri.simplices.astype(np.int64)
    a = np.concatenate([s[:, 0], s[:, 1], s[:, 0]])
    b = np.concatenate([s[:, 1], s[:, 2], s[:, 2]])
    if len(tri.coplanar):
        a = np.concatenate([a, tri.coplanar[:, 0]])
        b = np.concatenate([b, tri.coplanar[:, 2]])
    # one integer per edge: a 1-D unique, where unique over rows took 4 of the 5 ms
    n = len(points)
    key = np.unique(np.minimum(a, b) * n + np.maximum(a, b))
    return np.column_stack([key // n, key % n])


def find_root(parent, x):
    """Root of ``x`` in a union-find forest (list or int array), halving the path."""
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


def union_min(parent, a, b) -> bool:
    """Join the trees of ``a`` and ``b`` under the smaller root; False if already one."""
    ra, rb = find_root(parent, a), find_root(parent, b)
    if ra == rb:
        return False
    parent[max(ra, rb)] = min(ra, rb)
    return True


def distance_partitions(points: np.ndarray, d_min: float, d_max: float,
                        max_thresholds: int) -> tuple[list[np.ndarray], int]:
    """
    Label arrays of distance partitioning for all distinct thresholds in ``[d_min, d_max]``.

    Returns
    -------
    partitions : list of (m,) int arrays
        From the finest (threshold ``d_min``) to the coarsest; a label is the smallest
        detection index of its cell.
    dropped : int
        Distinct thresholds left out by ``max_thresholds`` (evenly thinned).

    Notes
    -----
    The single-linkage merges are applied in ascending height and the labels read at each
    kept threshold.

    """
    n = len(points)
    if n == 0:
        return [], 0
    a, b, length = _merges(points, d_max)
    # thresholds: d_min, then every distinct merge height in (d_min, d_max] (the merges
    # come in ascending height, so the distinct ones follow a change)
    above = length[length > d_min]
    distinct = np.empty(len(above), dtype=bool)
    distinct[:1] = True
    np.not_equal(above[1:], above[:-1], out=distinct[1:])
    thresholds = np.concatenate([[d_min], above[distinct]])
    dropped = 0
    if len(thresholds) > max_thresholds:
        keep = np.unique(np.round(np.linspace(0, len(thresholds) - 1,
                                              max_thresholds)).astype(int))
        dropped = len(thresholds) - len(keep)
        thresholds = thresholds[keep]
    stops = length.searchsorted(thresholds, side='right').tolist()
    if n <= PASS_MAX_RETURNS:
        return _labels_by_pass(a, b, stops, n), dropped
    return _labels_by_jumping(a, b, stops, n), dropped


# up to this many returns the labels are read by a Python pass over the forest at each
# threshold (a few microseconds); past it by numpy pointer jumping, whose cost per
# threshold hardly grows with n (the two cross near 100 returns)
PASS_MAX_RETURNS = 100


def _labels_by_pass(a: list, b: list, stops: list, n: int) -> list[np.ndarray]:
    """Labels at each stop: the merges up to it, then one pass reading the roots."""
    # each merge joins two roots (smallest indices) under the smaller one, so a parent is
    # always below its child: one pass in index order reads every root off its parent's
    parent = list(range(n))
    out = []
    done = 0
    for stop in stops:
        for i in range(done, stop):
            parent[b[i]] = a[i]
        done = stop
        labels = parent.copy()
        for i in range(n):
            labels[i] = labels[labels[i]]
        out.append(np.array(labels, dtype=np.int64))
    return out


def _labels_by_jumping(a: list, b: list, stops: list, n: int) -> list[np.ndarray]:
    """The same labels as :func:`_labels_by_pass`, the roots found by pointer jumping."""
    parent = np.arange(n)
    lo, hi = np.array(a, dtype=np.int64), np.array(b, dtype=np.int64)
    out = []
    done = 0
    for stop in stops:
        if done < stop:
            parent[hi[done:stop]] = lo[done:stop]
            parent = _roots(parent)
            done = stop
        out.append(parent.copy())
    return out


def _roots(parent: np.ndarray) -> np.ndarray:
    """Root of every node of a union-find forest by pointer jumping (vectorised)."""
    labels = parent
    while True:
        nxt = labels[labels]
        if np.all(nxt == labels):
            return labels
        labels = nxt


def _sums_by(labels: np.ndarray, points: np.ndarray, n: int) -> np.ndarray:
    """(n, 2) sums of the points of each label ``0..n-1``."""
    out = np.empty((n, 2))
    out[:, 0] = np.bincount(labels, weights=points[:, 0], minlength=n)
    out[:, 1] = np.bincount(labels, weights=points[:, 1], minlength=n)
    return out


_THREAD = threading.local()      # generators are stateful: one set per thread


def _seeded_generator(seed: int) -> np.random.Generator:
    """
    ``np.random.default_rng(seed)`` as new: a cached generator (per thread) put back to
    its seeded state; expanding a seed sequence costs tens of microseconds per k-means.
    """
    cache = getattr(_THREAD, 'generators', None)
    if cache is None:
        cache = _THREAD.generators = {}
    entry = cache.get(seed)
    if entry is None:
        gen = np.random.default_rng(seed)
        entry = cache[seed] = (gen, gen.bit_generator.state)
    entry[0].bit_generator.state = entry[1]
    return entry[0]


def kmeans_pp(points: np.ndarray, k: int, seed: int = 0, iters: int = 20,
              init: np.ndarray | None = None) -> np.ndarray:
    """
    Deterministic k-means (k-means++ seeding unless ``init`` centres are given).

    Returns the label of each point; empty clusters are dropped from the labels.
    """
    n = len(points)
    if k >= n:
        return np.arange(n)
    x, y = points[:, 0], points[:, 1]
    if init is None:
        rng = _seeded_generator(seed)
        first = points[rng.integers(n)]
        centres = [first]
        dx, dy = x - first[0], y - first[1]
        d2 = dx * dx + dy * dy                                 # to the nearest centre so far
        for _ in range(1, k):
            total = np.sum(d2)
            if total <= 0:
                break
            # rng.choice(n, p=d2 / total) without its argument checks: the same cdf, the
            # same single uniform draw, the same index
            cdf = (d2 / total).cumsum()
            cdf /= cdf[-1]
            c = points[int(cdf.searchsorted(rng.random(), side='right'))]
            centres.append(c)
            dx, dy = x - c[0], y - c[1]
            np.minimum(d2, dx * dx + dy * dy, out=d2)
        centres = np.array(centres)
    else:
        centres = np.array(init, dtype=float)
    labels = np.zeros(n, dtype=np.int64)
    # squares as products (x ** 2 is x * x in numpy, bit for bit, but a Python operand
    # costs each call more than the arithmetic here); the centres' coordinates as arrays
    # of their own, not columns of a (k, 2) array rebuilt each iteration
    x_col, y_col = x[:, None], y[:, None]
    k = len(centres)
    cx, cy = centres[:, 0], centres[:, 1]
    for _ in range(iters):
        dx, dy = x_col - cx, y_col - cy
        new = (dx * dx + dy * dy).argmin(axis=1)
        if _ and np.all(new == labels):       # not array_equal's wrapper
            break
        labels = new
        # each centre moves to the mean of its points; an empty cluster's centre stays
        count = np.bincount(labels, minlength=k)
        sx = np.bincount(labels, weights=x, minlength=k)
        sy = np.bincount(labels, weights=y, minlength=k)
        filled = count > 0
        if np.all(filled):
            cx, cy = sx / count, sy / count
        else:
            cx[filled] = sx[filled] / count[filled]
            cy[filled] = sy[filled] / count[filled]
    return labels


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
