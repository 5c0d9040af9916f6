"""The one label model: the oriented boxes of one image as arrays.

Every lenient reader of :mod:`aerial_synth.formats` (``dota.read_labels``,
``yolo_obb.labels_from_lines``, ``vedai.labels_from_lines``) returns an :class:`ImageLabels`;
``eval``, ``mix``, ``stats`` and ``show`` work on it. Its arrays are checked when it is made,
so a wrong shape fails where it was built, not deep inside the AP computation.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import LabelFormatError
from ..safe_input import read_text, shown

__all__ = ["ImageLabels", "read_lines"]


def read_lines(path) -> list[str]:
    """Text lines of a real-world label or prediction file (UTF-8, a byte-order mark ignored)."""
    # a link out of the input folder, a FIFO or a device is never read
    return read_text(path, shown(path), LabelFormatError).removeprefix("\ufeff").splitlines()


@dataclass
class ImageLabels:
    """Labels of one image.

    Parameters
    ----------
    name : str
        Image name (file stem; a collection prefixes its subfolder).
    polygons_xy_px : (n, 4, 2) float64
        Box corners, pixels, image frame (x right, y down, origin top-left).
    classes : list of str
        n class names.
    difficult : (n,) bool
    gsd_m : float or None
        Metres per pixel, when the file says.
    image_source : str or None
        DOTA's ``imagesource:`` header.
    label_path, image_path : Path or None
    size_wh : (int, int) or None
        Image width and height in pixels, when known.
    scores : (n,) float64 or None
        Confidences of predictions; None for ground truth.
    extra : dict
        Reader- or tool-specific notes (layout, statistics bookkeeping).

    Raises
    ------
    ValueError
        When the arrays do not have these shapes (as supervision's ``Detections`` does).
    """

    name: str
    polygons_xy_px: np.ndarray
    classes: list[str]
    difficult: np.ndarray
    gsd_m: float | None = None
    image_source: str | None = None
    label_path: Path | None = None
    image_path: Path | None = None
    size_wh: tuple[int, int] | None = None
    extra: dict = field(default_factory=dict)
    scores: np.ndarray | None = None

    def __post_init__(self) -> None:
        poly = np.asarray(self.polygons_xy_px, dtype=np.float64)
        if poly.size == 0:
            poly = poly.reshape(0, 4, 2)
        if poly.ndim != 3 or poly.shape[1:] != (4, 2):
            raise ValueError(f"ImageLabels {self.name!r}: polygons_xy_px must be (n, 4, 2), "
                             f"got shape {poly.shape}")
        n = len(poly)
        self.classes = list(self.classes)
        if len(self.classes) != n:
            raise ValueError(f"ImageLabels {self.name!r}: {n} polygons but {len(self.classes)} classes")
        diff = np.asarray(self.difficult)
        if diff.shape != (n,):
            raise ValueError(f"ImageLabels {self.name!r}: difficult must be ({n},), got shape {diff.shape}")
        if self.scores is not None:
            scores = np.asarray(self.scores, dtype=np.float64)
            if scores.shape != (n,):
                raise ValueError(f"ImageLabels {self.name!r}: scores must be ({n},), got shape {scores.shape}")
            self.scores = scores
        self.polygons_xy_px = poly
        self.difficult = diff.astype(bool, copy=False)

    def __len__(self) -> int:
        return len(self.classes)

    def keep_classes(self, classes) -> np.ndarray:
        """Keep only the objects whose class is in ``classes`` (None: every one), in place.
        Returns the (n,) bool mask of the objects kept, in the order they had."""
        keep = np.array([classes is None or c in classes for c in self.classes], bool)
        self.polygons_xy_px = np.asarray(self.polygons_xy_px, np.float64).reshape(-1, 4, 2)[keep]
        self.classes = [c for c, k in zip(self.classes, keep) if k]
        self.difficult = np.asarray(self.difficult, bool).reshape(-1)[keep]
        if self.scores is not None:
            self.scores = np.asarray(self.scores, np.float64)[keep]
        return keep
