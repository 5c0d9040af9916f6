"""Top-down contact sheet of catalog variants, rendered through the project's ray caster.

Every variant stands on a grey ground plane, heading 0 (+x = forward = right in the
image), one row per model and one column per colour. Orthographic vertical rays are cast
through :class:`aerial_synth.scene.raycast.RayScene`; each hit is shaded with Lambert
from a sun direction (hit normal, face albedo), plus an ambient term and cast shadows.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigError
from ..io_utils import atomic_write_bytes, check_output_file
from ..memory import check_memory
from ..safe_input import MAX_IMAGE_PIXELS, MAX_IMAGE_SIDE
from ..scene.model import Scene, SceneObject
from ..scene.raycast import RayScene
from .catalog import Catalog, load_catalog
from .meshes import build_mesh
from .model import VehicleVariant

__all__ = ["render_contact_sheet", "render_top_down", "write_contact_sheet"]

_GROUND_RGB = (0.42, 0.42, 0.40)


def _sun_direction(azimuth_deg: float, elevation_deg: float) -> np.ndarray:
    """Unit vector toward the sun; azimuth counter-clockwise from +x (east), world frame."""
    a, e = np.radians(azimuth_deg), np.radians(elevation_deg)
    return np.array([np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)])


def render_top_down(
    variants: list[VehicleVariant],
    centres_xy: np.ndarray,
    extent_xy: tuple[float, float, float, float],
    gsd_m: float = 0.04,
    sun_azimuth_deg: float = 135.0,
    sun_elevation_deg: float = 50.0,
    ambient: float = 0.35,
) -> np.ndarray:
    """Render vehicles (heading 0) seen straight down; returns an (h, w, 3) uint8 RGB image.

    centres_xy : (k, 2) float, metres, world: footprint centre of each variant
    extent_xy  : (xmin, ymin, xmax, ymax) metres, world, of the image; image x = world x,
                 image y = -world y (north up)
    gsd_m      : metres per pixel
    """
    xmin, ymin, xmax, ymax = extent_xy
    w = int(round((xmax - xmin) / gsd_m))
    h = int(round((ymax - ymin) / gsd_m))
    pad = 5.0
    ground = SceneObject(
        name="ground",
        label="ground",
        vertices=np.array(
            [[xmin - pad, ymin - pad, 0.0], [xmax + pad, ymin - pad, 0.0],
             [xmax + pad, ymax + pad, 0.0], [xmin - pad, ymax + pad, 0.0]]
        ),
        faces=np.array([[0, 1, 2], [0, 2, 3]]),
        material="asphalt",
        color=_GROUND_RGB,
    )
    rs = RayScene(Scene(name="contact-sheet", objects=[ground]))
    for k, (var, c) in enumerate(zip(variants, np.asarray(centres_xy, float))):
        mesh = build_mesh(var.model, var.color)
        v, f = mesh.to_world(c[0], c[1], 0.0, 0.0)
        rs.add_vehicle(k + 1, v, f, mesh.face_material, mesh.face_albedo)

    px = xmin + (np.arange(w) + 0.5) * gsd_m
    py = ymax - (np.arange(h) + 0.5) * gsd_m
    gx, gy = np.meshgrid(px, py)
    z0 = 20.0
    rays = np.zeros((w * h, 6), np.float32)
    rays[:, 0] = gx.ravel()
    rays[:, 1] = gy.ravel()
    rays[:, 2] = z0
    rays[:, 5] = -1.0
    hits = rs.cast_rays(rays)
    ok = hits.hit
    fi = np.where(ok, hits.face, 0)
    albedo = np.where(ok[:, None], rs.face_albedo[fi], 0.0)
    normal = hits.normal.astype(np.float64)
    sun = _sun_direction(sun_azimuth_deg, sun_elevation_deg)
    lam = np.clip(normal @ sun, 0.0, None)
    # cast shadows: a ray from just above each hit toward the sun
    pts = rays[:, :3].astype(np.float64)
    pts[:, 2] -= hits.t.astype(np.float64)
    pts = np.where(ok[:, None], pts + normal * 2e-3, 0.0)
    srays = np.zeros_like(rays)
    srays[:, :3] = pts
    srays[:, 3:] = sun
    shadow = rs.cast_rays(srays[ok]).hit
    lit = np.zeros(len(rays), bool)
    lit[np.flatnonzero(ok)] = ~shadow
    shade = ambient + (1.0 - ambient) * lam * lit / max(np.sin(np.radians(sun_elevation_deg)), 1e-3)
    shade = np.clip(shade, 0.0, 1.6)
    rgb = np.clip(albedo * shade[:, None], 0.0, 1.0) ** (1 / 2.2)
    img = (rgb.reshape(h, w, 3) * 255.0 + 0.5).astype(np.uint8)
    return img


#: Peak memory of a contact sheet per pixel of its ray grid: 230-240 B measured (peak RSS
#: 2.98 GB at 0.04 m/px, 4988 x 2410 px; 11.1 GB at 0.02 m/px, 9745 x 4787 px).
SHEET_BYTES_PER_PX = 240


def check_sheet_memory(width_m: float, height_m: float, gsd_m: float, available=None) -> None:
    """Refuse a sheet of ``width_m`` x ``height_m`` at ``gsd_m`` whose ray grid cannot fit in
    memory (or exceeds OpenCV's image size), before anything is allocated."""
    w, h = width_m / gsd_m, height_m / gsd_m
    coarsest = max(gsd_m * math.sqrt(w * h / MAX_IMAGE_PIXELS), width_m / MAX_IMAGE_SIDE)
    if w * h > MAX_IMAGE_PIXELS or max(w, h) > MAX_IMAGE_SIDE:
        raise ConfigError(f"--gsd {gsd_m:g}: the contact sheet would be {w:.0f} x {h:.0f} px, more "
                          f"than OpenCV's limit of {MAX_IMAGE_PIXELS:,} pixels; choose --gsd "
                          f">= {coarsest:.3g}")
    at_default = width_m * height_m / 0.04 ** 2 * SHEET_BYTES_PER_PX
    check_memory(int(w * h * SHEET_BYTES_PER_PX),
                 f"--gsd {gsd_m:g}: a contact sheet of {w:.0f} x {h:.0f} px",
                 f"choose a coarser --gsd (0.04 needs {at_default / 1e9:.1f} GB)",
                 ConfigError, available)


def render_contact_sheet(
    catalog: Catalog,
    gsd_m: float = 0.04,
    sun_azimuth_deg: float = 135.0,
    sun_elevation_deg: float = 50.0,
) -> np.ndarray:
    """Contact sheet of every variant: rows = models, columns = colours, with labels.

    Returns an (H, W, 3) uint8 BGR image (OpenCV order, ready for ``cv2.imencode``).
    """
    import cv2

    models, colors = catalog.models, catalog.colors
    cell_w_m = max(m.length_m for m in models) + 0.8
    row_h_m = [m.width_m + 0.9 for m in models]
    n_cols = len(colors)
    width_m = cell_w_m * n_cols
    height_m = float(sum(row_h_m))
    check_sheet_memory(width_m, height_m, gsd_m)
    variants, centres = [], []
    y_top = height_m
    for m, rh in zip(models, row_h_m):
        yc = y_top - rh / 2
        for j, c in enumerate(colors):
            variants.append(VehicleVariant(m, c))
            centres.append((cell_w_m * (j + 0.5), yc))
        y_top -= rh
    img = render_top_down(
        variants, np.array(centres), (0.0, 0.0, width_m, height_m), gsd_m=gsd_m,
        sun_azimuth_deg=sun_azimuth_deg, sun_elevation_deg=sun_elevation_deg,
    )
    img = cv2.cvtColor(img, cv2.COLOR_RGB2BGR)
    # at coarse GSDs, enlarge the pixels (nearest) so every row and column has room for labels
    up = max(1, int(np.ceil(max(60.0 / (min(row_h_m) / gsd_m), 160.0 / (cell_w_m / gsd_m)))))
    if up > 1:
        img = cv2.resize(img, None, fx=up, fy=up, interpolation=cv2.INTER_NEAREST)
    px_per_m = up / gsd_m
    h, w = img.shape[:2]
    font = cv2.FONT_HERSHEY_SIMPLEX
    left, top = 230, 34
    sheet = np.full((h + top, w + left, 3), 255, np.uint8)
    sheet[top:, left:] = img
    wsum = sum(k.weight for k in colors)
    # column headers: colour swatch, name and share
    for j, c in enumerate(colors):
        x0 = left + int(round(cell_w_m * j * px_per_m))
        sw = (np.array(c.rgb[::-1]) ** (1 / 2.2) * 255).astype(int).tolist()
        cv2.rectangle(sheet, (x0 + 6, 8), (x0 + 24, 26), sw, -1)
        cv2.rectangle(sheet, (x0 + 6, 8), (x0 + 24, 26), (0, 0, 0), 1)
        share = c.weight / wsum
        txt = f"{c.name} {share:.0%}" if share >= 0.01 else f"{c.name} {share:.1%}"
        cv2.putText(sheet, txt, (x0 + 30, 24), font, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
        if j:
            cv2.line(sheet, (x0, top), (x0, h + top), (255, 255, 255), 1)
    # row headers: model name, size, class, pack
    y = top
    for m, rh in zip(models, row_h_m):
        rpx = int(round(rh * px_per_m))
        lines = [m.name, f"{m.length_m:.2f} x {m.width_m:.2f} x {m.height_m:.2f} m",
                 f"{m.cls}, pack {m.pack}"]
        for k, t in enumerate(lines):
            cv2.putText(sheet, t, (8, y + rpx // 2 - 14 + 17 * k), font, 0.48 if k else 0.55,
                        (0, 0, 0), 2 if k == 0 else 1, cv2.LINE_AA)
        y += rpx
        cv2.line(sheet, (0, y), (w + left, y), (255, 255, 255), 1)
    cv2.putText(sheet, f"{gsd_m * 100:.0f} cm/px, +x forward ->", (8, 24), font, 0.5, (0, 0, 0),
                1, cv2.LINE_AA)
    return sheet


def write_contact_sheet(out, catalog_path=None, gsd_m: float = 0.04) -> tuple[int, int, int]:
    """``aerial-synth assets preview``: the contact sheet of every variant of the catalog
    (the bundled one when ``catalog_path`` is None) written atomically as PNG to ``out``.
    Returns (variants, width px, height px)."""
    import cv2

    check_output_file(out)
    cat = load_catalog(catalog_path)
    sheet = render_contact_sheet(cat, gsd_m=gsd_m)
    ok, buf = cv2.imencode(".png", sheet, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    if not ok:  # pragma: no cover - OpenCV failure
        raise RuntimeError("PNG encoding failed")
    atomic_write_bytes(out, buf.tobytes())
    h, w = sheet.shape[:2]
    return len(cat.models) * len(cat.colors), w, h
