"""The records a :class:`~aerial_synth.scene.raycast.RayScene` answers with: ray hits and
vertical traces (arrays of n rays or points, world frame, metres)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np

from .model import LABEL_IDS, LABELS

__all__ = ["RayHits", "TraceResult"]


@dataclass(frozen=True)
class RayHits:
    """Result of :meth:`RayScene.cast_rays` for n rays.

    t           : (n,) float32, distance along the (unit or not) ray direction; inf on miss
    face        : (n,) int64, global face index into the RayScene tables; -1 on miss
    label_id    : (n,) int16, semantic id (see model.LABELS); 0 on miss
    instance_id : (n,) int32, vehicle instance id; 0 for non-vehicles and misses
    normal      : (n, 3) float32, geometric normal of the hit triangle (world); 0 on miss
    """

    t: np.ndarray
    face: np.ndarray
    label_id: np.ndarray
    instance_id: np.ndarray
    normal: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return self.face >= 0


@dataclass(frozen=True)
class TraceResult:
    """Result of :meth:`RayScene.trace_down` for n points.

    z           : (n,) float64, hit height in metres (world z); nan on miss
    label_id    : (n,) int16 semantic id; 0 (``unknown``) on miss
    object_index: (n,) int32 index into ``scene.objects``; -1 for vehicles and misses
    instance_id : (n,) int32 vehicle id; 0 otherwise
    """

    z: np.ndarray
    label_id: np.ndarray
    object_index: np.ndarray
    instance_id: np.ndarray

    @property
    def labels(self) -> list[str]:
        return [LABELS[i] for i in self.label_id]

    def is_label(self, names: Iterable[str]) -> np.ndarray:
        ids = [LABEL_IDS[n] for n in names]
        return np.isin(self.label_id, ids)
