"""
Distance partitioning: every distinct threshold in ``[d_min, d_max]`` by cutting one
single-linkage dendrogram (``doc/model.md``, section 5).
"""

from __future__ import annotations

import numpy as np
from scipy.cluster.hierarchy import linkage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import minimum_spanning_tree
from scipy.spatial import cKDTree, Delaunay, QhullError
from scipy.spatial.distance import pdist

LINKAGE_MAX = 1150      # up to this many detections: scipy's single linkage on all pairs


def single_linkage_merges(points: np.ndarray, d_max: float):
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
    pairs = delaunay_pairs(points)
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


def delaunay_pairs(points: np.ndarray):
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
    a, b, length = single_linkage_merges(points, d_max)
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
        if (nxt == labels).all():
            return labels
        labels = nxt
