"""placement.png: the top-down scene map with vehicle rectangles, heading ticks and lines."""

from __future__ import annotations

import colorsys

import numpy as np

from ..safe_input import cv_text
from .model import Placement, footprint_corners_xy

__all__ = ["draw_placement", "line_color_bgr"]


def line_color_bgr(line_id: int, lane: int) -> tuple[int, int, int]:
    """A distinct, bright colour per traffic line (golden-ratio hue walk); the opposite lane
    of a line gets the same hue, darker."""
    if line_id < 0:
        return (0, 0, 255)
    h = (line_id * 0.6180339887) % 1.0
    r, g, b = colorsys.hsv_to_rgb(h, 0.9, 1.0 if lane == 0 else 0.7)
    return (int(b * 255), int(g * 255), int(r * 255))


def draw_placement(view, placement: Placement, title: str | None = None) -> np.ndarray:
    """Draw ``placement`` on a :class:`~aerial_synth.scene.mapview.MapView`.

    Returns a new (H, W, 3) uint8 BGR image: each vehicle's footprint rectangle (filled in its
    line's colour, outlined dark), a white tick from the centre to the front, and a thin
    polyline joining consecutive vehicles of a line.
    """
    import cv2

    img = view.image.copy()
    vs = placement.vehicles
    if not vs:
        return img
    s = 1 << 3  # sub-pixel precision for cv2 drawing
    by_line: dict[tuple[int, int], list] = {}
    for v in vs:
        by_line.setdefault((v.line_id, v.lane), []).append(v)
    for (lid, lane), group in by_line.items():
        if lid < 0 or len(group) < 2:
            continue
        pts = view.world_to_px(np.array([[v.x_m, v.y_m] for v in group]))
        cv2.polylines(img, [np.round(pts * s).astype(np.int32)], False,
                      line_color_bgr(lid, lane), 1, cv2.LINE_AA, shift=3)
    x = np.array([v.x_m for v in vs])
    y = np.array([v.y_m for v in vs])
    h = np.array([v.heading_rad for v in vs])
    corners = footprint_corners_xy(x, y, h, [v.length_m for v in vs], [v.width_m for v in vs])
    for v, c in zip(vs, corners):
        px = np.round(view.world_to_px(c) * s).astype(np.int32)
        col = line_color_bgr(v.line_id, v.lane)
        cv2.fillPoly(img, [px], col, cv2.LINE_AA, shift=3)
        cv2.polylines(img, [px], True, (20, 20, 20), 1, cv2.LINE_AA, shift=3)
        a = view.world_to_px(np.array([[v.x_m, v.y_m]]))[0]
        front = view.world_to_px(
            np.array([[v.x_m + 0.5 * v.length_m * np.cos(v.heading_rad),
                       v.y_m + 0.5 * v.length_m * np.sin(v.heading_rad)]]))[0]
        cv2.line(img, tuple(np.round(a * s).astype(int)), tuple(np.round(front * s).astype(int)),
                 (255, 255, 255), 1, cv2.LINE_AA, shift=3)
    if title:
        title = cv_text(title)  # a scene file's name may hold bytes that are not UTF-8
        # white text on a dark band (a thick black outline drawn under thin white text
        # advances differently per glyph in Hershey fonts and leaves a ghost of the title)
        (tw, th), base = cv2.getTextSize(title, cv2.FONT_HERSHEY_SIMPLEX, 0.6, 1)
        cv2.rectangle(img, (4, 24 - th - 6), (16 + tw, 24 + base + 2), (0, 0, 0), -1)
        cv2.putText(img, title, (10, 24), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)
    return img
