"""Top-down label map of a scene (north up), rasterised with vertical ray traces.

Every pixel centre gets one trace with nothing ignored (what a camera sees) and one with
the label config's ignore-set (what placement sees); tree crowns are blended
semi-transparently over the surface below them so overhanging crowns show the road.
The image is BGR uint8 (OpenCV order). Other stages (placement) draw on top of it with
:meth:`MapView.world_to_px`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ConfigError, RenderError, SceneError
from ..io_utils import atomic_write_bytes
from ..validators import integer, positive
from .model import LABEL_IDS, LABELS, Scene
from .raycast import RayScene

__all__ = ["MapView", "LABEL_COLORS_BGR", "render_map", "save_png"]

#: Map colour per label, BGR uint8.
LABEL_COLORS_BGR: dict[str, tuple[int, int, int]] = {
    "unknown": (255, 0, 255),
    "road": (70, 70, 70),
    "lane_marking": (235, 235, 235),
    "sidewalk": (160, 170, 180),
    "parking": (110, 100, 95),
    "ground": (80, 150, 95),
    "water": (200, 120, 40),
    "building": (60, 80, 170),
    "tree": (30, 100, 30),
    "trunk": (30, 60, 110),
    "pole": (0, 200, 255),
    "vehicle": (0, 0, 255),
    "parking_marking": (210, 225, 235),
}
_NOTHING_BGR = (0, 0, 0)
_TREE_ALPHA = 0.55


@dataclass(frozen=True)
class MapView:
    """A north-up raster of a scene.

    image     : (H, W, 3) uint8, BGR (OpenCV order)
    origin_xy : (2,) float, metres, world xy of the top-left corner of pixel (0, 0)
    m_per_px  : metres per pixel (square pixels)
    """

    image: np.ndarray
    origin_xy: np.ndarray
    m_per_px: float

    @property
    def size_wh(self) -> tuple[int, int]:
        return int(self.image.shape[1]), int(self.image.shape[0])

    def world_to_px(self, xy: np.ndarray) -> np.ndarray:
        """World xy (n, 2) metres -> (n, 2) float pixel coordinates (x right, y down).

        Integer values are pixel corners: pixel (i, j) covers [j, j+1) x [i, i+1), so its
        centre is at (j + 0.5, i + 0.5).
        """
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        u = (xy[:, 0] - self.origin_xy[0]) / self.m_per_px
        v = (self.origin_xy[1] - xy[:, 1]) / self.m_per_px
        return np.column_stack([u, v])

    def px_to_world(self, uv: np.ndarray) -> np.ndarray:
        """Inverse of :meth:`world_to_px`: (n, 2) px -> (n, 2) metres, world xy."""
        uv = np.asarray(uv, dtype=np.float64).reshape(-1, 2)
        x = self.origin_xy[0] + uv[:, 0] * self.m_per_px
        y = self.origin_xy[1] - uv[:, 1] * self.m_per_px
        return np.column_stack([x, y])


def _palette() -> np.ndarray:
    pal = np.zeros((len(LABELS) + 1, 3), np.float32)
    for name, col in LABEL_COLORS_BGR.items():
        pal[LABEL_IDS[name]] = col
    return pal


def render_map(
    scene: Scene,
    m_per_px: float = 0.5,
    rayscene=None,
    legend: bool = True,
    max_px: int = 8000,
) -> MapView:
    """Rasterise ``scene`` top-down at ``m_per_px`` metres per pixel.

    rayscene : an existing :class:`~aerial_synth.scene.raycast.RayScene` to reuse (its
               vehicles are drawn too); built from ``scene`` when None
    legend   : draw a scale bar and a label legend
    Returns a :class:`MapView` covering the scene's xy bounds.
    """
    if not isinstance(scene, Scene):
        raise SceneError(f"render_map scene: expected a Scene, got {type(scene).__name__}")
    m_per_px = positive("--m-per-px", m_per_px)
    max_px = integer("render_map max_px", max_px, 1, 1 << 16, error=SceneError)
    b = scene.bounds()
    if not np.isfinite(b).all():
        raise SceneError(f"render_map scene {scene.name!r}: expected finite bounds, got {b.tolist()}")
    x0, y0, x1, y1 = b[0, 0], b[0, 1], b[1, 0], b[1, 1]
    W = max(1, int(np.ceil((x1 - x0) / m_per_px)))
    H = max(1, int(np.ceil((y1 - y0) / m_per_px)))
    if max(W, H) > max_px:
        need = max(x1 - x0, y1 - y0) / max_px
        raise ConfigError(
            f"--m-per-px: {m_per_px:g} gives a {W}x{H} px map of {scene.name} "
            f"({x1 - x0:.0f} m x {y1 - y0:.0f} m); expected at least {need:.3g} m/px "
            f"(at most {max_px} px a side)"
        )
    if rayscene is None:
        rayscene = RayScene(scene)
    origin = np.array([x0, y1], dtype=np.float64)
    pal = _palette()
    top, top_hit = (a.ravel() for a in rayscene.trace_grid(origin, m_per_px, W, H, ignore=()))
    img = pal[top]
    ign = tuple(sorted(rayscene.label_config.ignore))
    if ign:
        over = np.isin(top, [LABEL_IDS[n] for n in ign])
        under, under_hit = (a.ravel()[over] for a in
                            rayscene.trace_grid(origin, m_per_px, W, H, ignore=ign))
        below = pal[under]
        below[~under_hit] = _NOTHING_BGR
        img[over] = _TREE_ALPHA * pal[top[over]] + (1 - _TREE_ALPHA) * below
    img[~top_hit] = _NOTHING_BGR
    image = np.clip(img, 0, 255).astype(np.uint8).reshape(H, W, 3)
    view = MapView(image=image, origin_xy=origin, m_per_px=m_per_px)
    if legend:
        _draw_scale_bar(view)
        _draw_legend(view, {LABELS[i] for i in np.unique(top) if i > 0})
    if (scene.meta or {}).get("attribution"):  # OSM scenes: the data licence asks for it
        draw_attribution(view.image, str(scene.meta["attribution"]))
    return view


def draw_attribution(image: np.ndarray, text: str) -> None:
    """Draw a data attribution ("© OpenStreetMap contributors") in the bottom-right corner.
    OpenCV's fonts are ASCII only, so a leading "©" is drawn as a circled c."""
    import cv2

    H, W = image.shape[:2]
    mark = text.startswith("©")
    body = text[1:].strip() if mark else text
    font, scale = cv2.FONT_HERSHEY_SIMPLEX, 0.45
    (tw, th), _ = cv2.getTextSize(body, font, scale, 1)
    extra = 16 if mark else 0
    x1, y1 = W - 6, H - 6
    x0, y0 = max(0, x1 - tw - extra - 8), max(0, y1 - th - 10)
    cv2.rectangle(image, (x0, y0), (x1, y1), (255, 255, 255), -1)
    x = x0 + 4
    if mark:
        cy = (y0 + y1) // 2
        cv2.circle(image, (x + 6, cy), 6, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(image, "c", (x + 2, cy + 3), font, 0.35, (0, 0, 0), 1, cv2.LINE_AA)
        x += extra
    cv2.putText(image, body, (x, y1 - 5), font, scale, (0, 0, 0), 1, cv2.LINE_AA)


def _draw_scale_bar(view: MapView) -> None:
    import cv2

    H, W = view.image.shape[:2]
    target = 0.2 * W * view.m_per_px
    nice = [1, 2, 5, 10, 20, 25, 50, 100, 200, 250, 500, 1000, 2000, 5000]
    length_m = max([n for n in nice if n <= target] or [nice[0]])
    L = int(round(length_m / view.m_per_px))
    x, y = 10, H - 14
    cv2.rectangle(view.image, (x - 4, y - 20), (x + L + 60, y + 8), (255, 255, 255), -1)
    cv2.line(view.image, (x, y), (x + L, y), (0, 0, 0), 3)
    for xx in (x, x + L):
        cv2.line(view.image, (xx, y - 6), (xx, y + 4), (0, 0, 0), 2)
    cv2.putText(view.image, f"{length_m} m", (x + L + 6, y + 4), cv2.FONT_HERSHEY_SIMPLEX,
                0.45, (0, 0, 0), 1, cv2.LINE_AA)


def _draw_legend(view: MapView, present: set[str]) -> None:
    import cv2

    names = [n for n in LABELS if n in present]
    if not names:
        return
    H, W = view.image.shape[:2]
    row = 16
    w = 130
    x0, y0 = W - w - 8, 8
    cv2.rectangle(view.image, (x0 - 4, y0 - 4), (x0 + w, y0 + row * len(names) + 2),
                  (255, 255, 255), -1)
    for k, n in enumerate(names):
        y = y0 + k * row
        cv2.rectangle(view.image, (x0, y + 2), (x0 + 12, y + 13), LABEL_COLORS_BGR[n], -1)
        cv2.rectangle(view.image, (x0, y + 2), (x0 + 12, y + 13), (0, 0, 0), 1)
        cv2.putText(view.image, n, (x0 + 18, y + 12), cv2.FONT_HERSHEY_SIMPLEX, 0.4,
                    (0, 0, 0), 1, cv2.LINE_AA)


def save_png(path: str | Path, image: np.ndarray) -> Path:
    """Write a BGR (or grey) uint8 image as PNG, atomically."""
    import cv2

    ok, buf = cv2.imencode(".png", np.ascontiguousarray(image))
    if not ok:
        raise RenderError(f"cannot encode PNG for {path}")
    return atomic_write_bytes(path, buf.tobytes())
