"""
The counts of one scan: what each stage of the pipeline did.

One type for every stage: the pipeline makes one :class:`Diagnostics` per scan and each
stage fills its own fields. It reads as a mapping (``diag['cells']``, ``dict(diag)``), in
field order, which is the order the node publishes them in.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields


@dataclass(eq=False)
class Diagnostics(Mapping):
    """
    Counts of one scan.

    Attributes
    ----------
    detections : int
        Valid returns of the scan.
    background_dropped, warmup : int
        Returns dropped as background; 1 while the background warm-up runs.
    legs : int
        1 once the scans have shown legs: a walker's legs are partitioned as one cell
        (:mod:`sensing.legs`).
    left_view, at_sensor, sparse, absorbed : int
        Predicted components dropped: out of the field of view, holding the sensor, in
        view but expecting far fewer returns than the beams they span, standing on
        returns just learned as background.
    partitions, cells, pairs, components, births : int
        The update's partitions, distinct cells, gated (component, cell) pairs, components
        after reduction and new labels.
    capped_partitions, capped_cells, capped_components : int
        What the caps dropped.
    oversized : int
        Components dropped as too large or too uncertain.
    fused_labels, joined_labels, relabelled, handed_over, grouped : int
        Track management: labels fused into another, joined as parts of one object, given
        a new id after a jump, ids handed over, contour pieces reported as one object.
    unexplained : int
        1 when no partition explained the scan.
    held : int
        Components held from a miss while wholly in shadow.
    sparse_births : int
        Births refused as objects the sensor could not have seen.
    beams : int
        Beams of the scan; ``masked_<kind>`` the beams masked for each invalid kind.

    """

    detections: int = 0
    background_dropped: int = 0
    warmup: int = 0
    legs: int = 0
    left_view: int = 0
    at_sensor: int = 0
    sparse: int = 0
    absorbed: int = 0
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
    unexplained: int = 0
    held: int = 0
    sparse_births: int = 0
    beams: int = 0
    masked_nan: int = 0
    masked_pos_inf: int = 0
    masked_neg_inf: int = 0
    masked_below_min: int = 0
    masked_above_max: int = 0

    def __getitem__(self, key: str) -> int:
        if key not in self.__dataclass_fields__:
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self):
        return (f.name for f in fields(self))

    def __len__(self) -> int:
        return len(self.__dataclass_fields__)
