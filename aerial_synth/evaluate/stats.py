"""``aerial-synth stats``: dataset statistics and the domain-gap report.

Per dataset (labels from every image; pixel statistics from at most ``max_images`` images
drawn with ``numpy.random.default_rng(seed)``):

- ``vehicles_per_image``; box ``length_px``/``width_px`` (means of opposite edges, long /
  short) and ``length_m``/``width_m`` (times the image's GSD); ``aspect`` = length / width;
  ``heading_deg`` (rear-edge midpoint -> front-edge midpoint, the first two corners being the
  front as in DOTA, 0 = right, 90 = up, [0, 360)); ``axis_deg`` (long axis, [0, 180));
  ``nn_distance_px``/``_m`` (centre to the nearest other box centre of the same image);
- ``difficult_fraction``, ``truncated_fraction`` (a corner within 1 px of the border or
  outside the image), class counts and shares;
- per image: ``image_gray_mean``, ``image_gray_sd`` (8-bit gray, OpenCV BGR2GRAY),
  ``image_red_mean``/``green``/``blue``, ``image_saturation_mean`` (HSV S);
- per vehicle: ``box_gray_mean`` (inside the box), ``ring_gray_mean`` (a 4 px ring around
  it: the box dilated by a 9 x 9 ellipse, minus the box, minus every other box of the image),
  and ``vehicle_contrast`` = (box mean - ring mean) / the image's gray sd; the report quotes
  its median over vehicles (signed), the median of its absolute value (issue 15's figure)
  and the share of vehicles brighter than their ring;
- colour histograms (32 bins per channel, R G B) of all pixels, inside boxes and in rings.

With a second dataset: each distribution side by side, its two-sample KS statistic and
Wasserstein distance (``scipy.stats``; for the histograms, both computed on the binned
distributions), sorted by KS, largest first; plus differences of the fractions and class
shares. Plots are drawn with OpenCV.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import EvaluationError
from ..formats import CATEGORIES
from ..io_utils import atomic_write_bytes, atomic_write_json, atomic_write_text
from ..safe_input import (
    MAX_IMAGE_FILE_BYTES,
    check_image_pixels,
    decode_image,
    image_file_complete,
    read_bytes,
    shown,
)
from .labels import image_size, read_dataset
from .plots import grid, histogram_chart, line_chart, png_bytes

__all__ = ["DISTRIBUTIONS", "box_geometry", "vehicle_pixels", "dataset_stats", "compare_stats",
           "run_stats"]

#: name -> (unit / axis label, what each value is)
DISTRIBUTIONS = {
    "vehicles_per_image": ("vehicles", "per image"),
    "length_px": ("px", "per box"),
    "width_px": ("px", "per box"),
    "length_m": ("m", "per box"),
    "width_m": ("m", "per box"),
    "aspect": ("length / width", "per box"),
    "heading_deg": ("degrees (0 = right, 90 = up)", "per box"),
    "axis_deg": ("degrees, long axis", "per box"),
    "nn_distance_px": ("px", "per box"),
    "nn_distance_m": ("m", "per box"),
    "image_gray_mean": ("8-bit gray", "per image"),
    "image_gray_sd": ("8-bit gray", "per image"),
    "image_red_mean": ("8-bit", "per image"),
    "image_green_mean": ("8-bit", "per image"),
    "image_blue_mean": ("8-bit", "per image"),
    "image_saturation_mean": ("8-bit HSV S", "per image"),
    "box_gray_mean": ("8-bit gray", "per vehicle"),
    "ring_gray_mean": ("8-bit gray", "per vehicle"),
    "vehicle_contrast": ("(box - ring) / image gray sd", "per vehicle"),
}
RING_PX = 4
# BGR line colours of the R, G, B histograms: dataset A dark, dataset B light
_CHANNEL_COLOURS = {"A": ((20, 20, 190), (20, 140, 20), (190, 40, 20)),
                    "B": ((140, 140, 255), (130, 230, 130), (255, 190, 120))}
HIST_BINS = 32


def box_geometry(polygons_xy_px) -> dict[str, np.ndarray]:
    """(n, 4, 2) corners -> length, width (px), heading and axis (deg), centres (n, 2)."""
    P = np.asarray(polygons_xy_px, float).reshape(-1, 4, 2)
    e = np.linalg.norm(np.roll(P, -1, axis=1) - P, axis=2)  # edges p1p2, p2p3, p3p4, p4p1
    a = (e[:, 0] + e[:, 2]) / 2  # front and rear edges
    b = (e[:, 1] + e[:, 3]) / 2  # sides
    length, width = np.maximum(a, b), np.minimum(a, b)
    front = (P[:, 0] + P[:, 1]) / 2
    rear = (P[:, 2] + P[:, 3]) / 2
    d = front - rear
    heading = np.degrees(np.arctan2(-d[:, 1], d[:, 0])) % 360.0
    long_edge = np.where((a >= b)[:, None], P[:, 1] - P[:, 0], P[:, 2] - P[:, 1])
    axis = np.degrees(np.arctan2(-long_edge[:, 1], long_edge[:, 0])) % 180.0
    return {"length_px": length, "width_px": width, "heading_deg": heading, "axis_deg": axis,
            "centres": P.mean(axis=1)}


def _nn_distances(centres: np.ndarray) -> np.ndarray:
    if len(centres) < 2:
        return np.zeros(0)
    from scipy.spatial import cKDTree

    d, _ = cKDTree(centres).query(centres, k=2)
    return d[:, 1]


def _load_bgr(path: Path) -> np.ndarray | None:
    import cv2

    check_image_pixels(path, EvaluationError)  # over OpenCV's limit: refused, naming it
    if not image_file_complete(path):  # cut short: listed as unreadable, not half decoded
        return None
    # bytes to OpenCV, never a file name (undecodable names); a regular file only
    data = np.frombuffer(read_bytes(path, shown(path), EvaluationError,
                                    max_bytes=MAX_IMAGE_FILE_BYTES), np.uint8)
    img = decode_image(data, cv2.IMREAD_UNCHANGED)  # libpng's own messages silenced
    if img is None:
        return None
    if img.dtype == np.uint16:
        img = (img / 257.0).round().astype(np.uint8)
    elif img.dtype != np.uint8:
        img = np.clip(img, 0, 255).astype(np.uint8)
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    elif img.shape[2] == 4:
        img = img[:, :, :3]
    return img


def _centres_inside(p: np.ndarray, x0: int, y0: int, w: int, h: int) -> np.ndarray:
    """(h, w) bool: pixels of the window at (x0, y0) whose centres lie inside the polygon
    ``p`` (k, 2), px, image frame (crossing-number test, so any quad works)."""
    X = x0 + np.arange(w) + 0.5
    Y = (y0 + np.arange(h) + 0.5)[:, None]
    inside = np.zeros((h, w), bool)
    k = len(p)
    for i in range(k):
        (xa, ya), (xb, yb) = p[i], p[(i + 1) % k]
        if ya == yb:
            continue
        cond = (ya > Y) != (yb > Y)  # (h, 1): rows whose centre line crosses this edge
        xint = xa + (Y - ya) * (xb - xa) / (yb - ya)
        inside ^= cond & (X < xint)
    return inside


def vehicle_pixels(gray: np.ndarray, polygons_xy_px, ring_px: int = RING_PX):
    """Per box: mean gray inside and mean gray of the ring around it (NaN where empty),
    plus the union masks of all boxes and of all rings.

    Pixel (j, i) covers [j, j+1] x [i, i+1]; it is inside a box when its centre is. The ring
    is the box's pixels dilated by a (2 r + 1) x (2 r + 1) ellipse, minus the box, minus
    every box of the image."""
    import cv2

    h, w = gray.shape
    P = np.asarray(polygons_xy_px, float).reshape(-1, 4, 2)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * ring_px + 1, 2 * ring_px + 1))
    union = np.zeros((h, w), bool)
    crops = []
    for p in P:
        if not np.isfinite(p).all():
            crops.append(None)
            continue
        x0 = int(np.floor(p[:, 0].min())) - ring_px - 1
        y0 = int(np.floor(p[:, 1].min())) - ring_px - 1
        x1 = int(np.ceil(p[:, 0].max())) + ring_px + 2
        y1 = int(np.ceil(p[:, 1].max())) + ring_px + 2
        cx0, cy0, cx1, cy1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if cx1 <= cx0 or cy1 <= cy0:
            crops.append(None)
            continue
        mask = _centres_inside(p, x0, y0, x1 - x0, y1 - y0)
        crops.append((x0, y0, cx0, cy0, cx1, cy1, mask))
        union[cy0:cy1, cx0:cx1] |= mask[cy0 - y0:cy1 - y0, cx0 - x0:cx1 - x0]
    ring_union = np.zeros((h, w), bool)
    m_in = np.full(len(P), np.nan)
    m_ring = np.full(len(P), np.nan)
    for i, c in enumerate(crops):
        if c is None:
            continue
        x0, y0, cx0, cy0, cx1, cy1, mask = c
        ring = cv2.dilate(mask.astype(np.uint8), kernel).astype(bool) & ~mask
        sl = (slice(cy0 - y0, cy1 - y0), slice(cx0 - x0, cx1 - x0))
        mask, ring = mask[sl], ring[sl] & ~union[cy0:cy1, cx0:cx1]
        crop = gray[cy0:cy1, cx0:cx1]
        if mask.any():
            m_in[i] = crop[mask].mean()
        if ring.any():
            m_ring[i] = crop[ring].mean()
            ring_union[cy0:cy1, cx0:cx1] |= ring
    return m_in, m_ring, union, ring_union


def _hist(pixels_bgr: np.ndarray) -> np.ndarray:
    """(k, 3) BGR pixels -> (3, bins) R, G, B counts."""
    out = np.zeros((3, HIST_BINS))
    if len(pixels_bgr):
        for ch, col in enumerate((2, 1, 0)):
            out[ch] = np.bincount(pixels_bgr[:, col] // (256 // HIST_BINS), minlength=HIST_BINS)
    return out


VEHICLE_CLASSES = CATEGORIES  # the one list, the vehicle catalog's (formats.CATEGORIES)


def _pixel_stats(items, max_images: int, seed: int, dist: dict):
    """Pixel statistics on at most ``max_images`` images drawn by ``seed`` (appended to
    ``dist``): (the images drawn, those unreadable, colour histograms)."""
    import cv2  # lazy: OpenCV only for pixel statistics (start-up time)

    with_img = [it for it in items if it.image_path is not None]
    rng = np.random.default_rng(seed)
    if len(with_img) > max_images:
        pick = np.sort(rng.choice(len(with_img), max_images, replace=False))
        with_img = [with_img[i] for i in pick]
    hists = {r: np.zeros((3, HIST_BINS)) for r in ("overall", "inside", "ring")}
    unreadable: list[str] = []
    for it in with_img:
        img = _load_bgr(it.image_path)
        if img is None:
            unreadable.append(str(it.image_path))
            continue
        gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        sd = float(gray.std())
        dist["image_gray_mean"].append([float(gray.mean())])
        dist["image_gray_sd"].append([sd])
        means = img.reshape(-1, 3).mean(0)
        dist["image_blue_mean"].append([means[0]])
        dist["image_green_mean"].append([means[1]])
        dist["image_red_mean"].append([means[2]])
        dist["image_saturation_mean"].append([float(cv2.cvtColor(img, cv2.COLOR_BGR2HSV)[:, :, 1].mean())])
        step = max(1, int(np.sqrt(gray.size / 250_000)))  # histogram of at most ~250k pixels
        hists["overall"] += _hist(img[::step, ::step].reshape(-1, 3))
        if len(it):
            m_in, m_ring, inside, ring = vehicle_pixels(gray, it.extra["all_polygons"])
            m_in, m_ring = m_in[it.extra["keep"]], m_ring[it.extra["keep"]]
            dist["box_gray_mean"].append(m_in[np.isfinite(m_in)])
            dist["ring_gray_mean"].append(m_ring[np.isfinite(m_ring)])
            ok = np.isfinite(m_in) & np.isfinite(m_ring)
            if sd > 0:
                dist["vehicle_contrast"].append((m_in[ok] - m_ring[ok]) / sd)
            hists["inside"] += _hist(img[inside])
            hists["ring"] += _hist(img[ring])
    return with_img, unreadable, hists


def dataset_stats(path, *, gsd: float | None = None, max_images: int = 500, seed: int = 0,
                  classes=VEHICLE_CLASSES, option: str = "DIR"
                  ) -> tuple[dict, dict[str, np.ndarray], dict[str, np.ndarray]]:
    """-> (summary dict, distributions name -> values, colour histograms region -> (3, bins)).

    Box statistics cover the objects of ``classes`` (None: every class); every labelled
    object, whatever its class, is left out of the rings around vehicles."""

    layout, items = read_dataset(path, option)
    labelled = [it for it in items if not it.extra.get("unlabelled")]
    other_classes: dict[str, int] = {}
    for it in items:
        all_classes = it.classes
        it.extra["all_polygons"] = it.polygons_xy_px
        keep = it.extra["keep"] = it.keep_classes(classes)
        for c, k in zip(all_classes, keep):
            if not k:
                other_classes[c] = other_classes.get(c, 0) + 1
    dist: dict[str, list] = {k: [] for k in DISTRIBUTIONS}
    counts: dict[str, int] = {}
    n_obj = n_diff = n_trunc = n_trunc_known = 0
    gsds = []
    for it in labelled:
        n = len(it)
        dist["vehicles_per_image"].append(n)
        for c in it.classes:
            counts[c] = counts.get(c, 0) + 1
        n_obj += n
        n_diff += int(np.count_nonzero(it.difficult))
        g = it.gsd_m if it.gsd_m is not None else gsd
        if g is not None:
            gsds.append(g)
        if n == 0:
            continue
        geo = box_geometry(it.polygons_xy_px)
        for k in ("length_px", "width_px", "heading_deg", "axis_deg"):
            dist[k].append(geo[k])
        dist["aspect"].append(geo["length_px"] / np.maximum(geo["width_px"], 1e-9))
        nn = _nn_distances(geo["centres"])
        dist["nn_distance_px"].append(nn)
        if g is not None:
            dist["length_m"].append(geo["length_px"] * g)
            dist["width_m"].append(geo["width_px"] * g)
            dist["nn_distance_m"].append(nn * g)
        size = it.size_wh
        if size is None and it.image_path is not None:
            try:
                size = it.size_wh = image_size(it.image_path)
            except Exception:  # noqa: BLE001 - an unreadable image only loses this figure
                size = None
        if size is not None:
            P = it.polygons_xy_px
            t = ((P[..., 0] < 1) | (P[..., 1] < 1) | (P[..., 0] > size[0] - 1) | (P[..., 1] > size[1] - 1)).any(1)
            n_trunc += int(t.sum())
            n_trunc_known += n

    with_img, unreadable, hists = _pixel_stats(items, max_images, seed, dist)
    arrays = {k: (np.concatenate([np.atleast_1d(np.asarray(v, float)) for v in vals]) if vals else np.zeros(0))
              for k, vals in dist.items()}
    if not labelled:
        arrays["vehicles_per_image"] = np.zeros(0)
    summary = {
        "path": str(path),
        "layout": layout,
        "images": len(items),
        "labelled_images": len(labelled),
        "pixel_statistics_images": len(with_img) - len(unreadable),
        "unreadable_images": unreadable[:20],
        "objects": n_obj,
        "classes": dict(sorted(counts.items())),
        "class_shares": {c: n / n_obj for c, n in sorted(counts.items())} if n_obj else {},
        "classes_selected": None if classes is None else list(classes),
        "other_classes_left_out": dict(sorted(other_classes.items())),
        "difficult_fraction": (n_diff / n_obj) if n_obj else None,
        "truncated_fraction": (n_trunc / n_trunc_known) if n_trunc_known else None,
        "gsd_m": _describe(np.asarray(gsds, float)) if gsds else None,
        "vehicle_contrast_median": _median(arrays["vehicle_contrast"]),
        "vehicle_abs_contrast_median": _median(np.abs(arrays["vehicle_contrast"])),
        "vehicle_brighter_fraction": (float(np.mean(arrays["vehicle_contrast"] > 0))
                                      if len(arrays["vehicle_contrast"]) else None),
        "distributions": {k: _describe(v) for k, v in arrays.items()},
        "colour_histograms": {r: (h / max(h[0].sum(), 1)).round(6).tolist() for r, h in hists.items()},
    }
    return summary, arrays, hists


def _median(v: np.ndarray):
    return float(np.median(v)) if len(v) else None


def _describe(v: np.ndarray) -> dict | None:
    v = np.asarray(v, float)
    v = v[np.isfinite(v)]
    if not len(v):
        return None
    p5, p25, p50, p75, p95 = np.percentile(v, [5, 25, 50, 75, 95])
    return {"n": int(len(v)), "mean": float(v.mean()), "sd": float(v.std()), "min": float(v.min()),
            "p5": float(p5), "p25": float(p25), "median": float(p50), "p75": float(p75),
            "p95": float(p95), "max": float(v.max())}


def _binned_distances(ha: np.ndarray, hb: np.ndarray) -> tuple[float, float]:
    """KS (max CDF difference) and Wasserstein (in 8-bit units) of two histograms."""
    from scipy.stats import wasserstein_distance

    if ha.sum() <= 0 or hb.sum() <= 0:
        return float("nan"), float("nan")
    ca, cb = np.cumsum(ha) / ha.sum(), np.cumsum(hb) / hb.sum()
    centres = (np.arange(len(ha)) + 0.5) * (256 / len(ha))
    return float(np.abs(ca - cb).max()), float(wasserstein_distance(centres, centres, ha, hb))


def compare_stats(a: dict[str, np.ndarray], b: dict[str, np.ndarray], hist_a=None, hist_b=None) -> list[dict]:
    """Distance per distribution, largest KS first."""
    from scipy.stats import ks_2samp, wasserstein_distance

    gaps = []
    for k in DISTRIBUTIONS:
        va, vb = a.get(k, np.zeros(0)), b.get(k, np.zeros(0))
        va, vb = va[np.isfinite(va)], vb[np.isfinite(vb)]
        if len(va) < 2 or len(vb) < 2:
            continue
        ks = ks_2samp(va, vb)
        w = float(wasserstein_distance(va, vb))
        pooled = float(np.sqrt((va.var() + vb.var()) / 2))
        gaps.append({"name": k, "unit": DISTRIBUTIONS[k][0], "per": DISTRIBUTIONS[k][1],
                     "ks": float(ks.statistic), "ks_pvalue": float(ks.pvalue), "wasserstein": w,
                     "wasserstein_over_sd": (w / pooled) if pooled > 0 else None,
                     "n_a": int(len(va)), "n_b": int(len(vb)),
                     "median_a": float(np.median(va)), "median_b": float(np.median(vb))})
    if hist_a is not None and hist_b is not None:
        for region in ("overall", "inside", "ring"):
            for ch, cname in enumerate(("red", "green", "blue")):
                ks, w = _binned_distances(hist_a[region][ch], hist_b[region][ch])
                if not np.isfinite(ks):
                    continue
                gaps.append({"name": f"colour_histogram_{region}_{cname}", "unit": "8-bit",
                             "per": "pixel (32 bins)", "ks": ks, "ks_pvalue": None, "wasserstein": w,
                             "wasserstein_over_sd": None, "n_a": int(hist_a[region][ch].sum()),
                             "n_b": int(hist_b[region][ch].sum()), "median_a": None, "median_b": None})
    gaps.sort(key=lambda g: -g["ks"])
    return gaps


def _clean(obj):
    """JSON-safe: numpy scalars to Python, NaN/inf to None."""
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_clean(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        f = float(obj)
        return round(f, 6) if np.isfinite(f) else None
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def run_stats(path: Path, out: Path, *, compare: Path | None = None, gsd: float | None = None,
              compare_gsd: float | None = None, max_images: int = 500, seed: int = 0,
              classes=VEHICLE_CLASSES, report_as: Path | None = None) -> str:
    """Compute, write ``stats.json`` and PNG plots into ``out``; return the summary text
    (naming the report folder ``report_as``, default ``out``)."""

    sa, da, ha = dataset_stats(path, gsd=gsd, max_images=max_images, seed=seed, classes=classes,
                               option="DIR")
    sets = [("A", sa, da, ha)]
    if compare is not None:
        sb, db, hb = dataset_stats(compare, gsd=compare_gsd, max_images=max_images, seed=seed,
                                   classes=classes, option="--compare")
        sets.append(("B", sb, db, hb))
    label = {"A": Path(path).name or str(path)}
    if compare is not None:
        label["B"] = Path(compare).name or str(compare)
        if label["B"] == label["A"]:
            label = {"A": f"A: {label['A']}", "B": f"B: {label['B']}"}
    report: dict = {"format": "aerial-synth-stats", "version": 1,
                    "datasets": {k: s for k, s, _, _ in sets},
                    "labels": label, "classes": None if classes is None else list(classes), "ring_px": RING_PX, "seed": seed, "max_images": max_images}
    gaps = compare_stats(da, sets[1][2], ha, sets[1][3]) if compare is not None else []
    if compare is not None:
        report["gaps"] = gaps
        report["fraction_differences"] = _fraction_differences(sa, sets[1][1])
        by = {g["name"]: g for g in gaps}
        report["realism"] = {
            "vehicle_contrast_median": {"A": sa["vehicle_contrast_median"], "B": sets[1][1]["vehicle_contrast_median"]},
            "image_gray_mean": {"A": _get(sa, "image_gray_mean"), "B": _get(sets[1][1], "image_gray_mean"),
                                "ks": by.get("image_gray_mean", {}).get("ks")},
            "image_gray_sd": {"A": _get(sa, "image_gray_sd"), "B": _get(sets[1][1], "image_gray_sd"),
                              "ks": by.get("image_gray_sd", {}).get("ks")},
            "vehicle_contrast_ks": by.get("vehicle_contrast", {}).get("ks"),
            "vehicle_abs_contrast_median": {"A": sa["vehicle_abs_contrast_median"],
                                            "B": sets[1][1]["vehicle_abs_contrast_median"],
                                            "relative_difference": _relative(
                                                sa["vehicle_abs_contrast_median"],
                                                sets[1][1]["vehicle_abs_contrast_median"])},
            "vehicle_brighter_fraction": {"A": sa["vehicle_brighter_fraction"],
                                          "B": sets[1][1]["vehicle_brighter_fraction"]},
        }
    else:
        report["realism"] = {"vehicle_contrast_median": {"A": sa["vehicle_contrast_median"]},
                             "vehicle_abs_contrast_median": {"A": sa["vehicle_abs_contrast_median"]},
                             "vehicle_brighter_fraction": {"A": sa["vehicle_brighter_fraction"]},
                             "image_gray_mean": {"A": _get(sa, "image_gray_mean")},
                             "image_gray_sd": {"A": _get(sa, "image_gray_sd")}}

    # plots: one per distribution, an overview of the largest gaps, colour histograms
    charts = {}
    for k, (unit, per) in DISTRIBUTIONS.items():
        series = [(label[n], d[k]) for n, _, d, _ in sets if len(d.get(k, ())) > 0]
        if not series:
            continue
        title = k
        g = next((g for g in gaps if g["name"] == k), None)
        if g is not None:
            title += f"  KS {g['ks']:.3f}  W {g['wasserstein']:.3g}"
        rng = (0.0, 360.0) if k == "heading_deg" else (0.0, 180.0) if k == "axis_deg" else None
        charts[k] = histogram_chart(title, series, f"{unit} ({per})", bins=36 if rng else 40, range_=rng)
    written = []
    for k, img in charts.items():
        written.append(atomic_write_bytes(out / f"hist_{k}.png", png_bytes(img)))
    order = [g["name"] for g in gaps if g["name"] in charts] or list(charts)
    if order:
        written.append(atomic_write_bytes(out / "overview.png", png_bytes(grid([charts[k] for k in order[:9]]))))
    centres = (np.arange(HIST_BINS) + 0.5) * (256 / HIST_BINS)
    colour_charts = []
    for region in ("overall", "inside", "ring"):
        series = []
        for n, _, _, h in sets:
            tot = h[region][0].sum()
            if tot <= 0:
                continue
            for ch, cname in enumerate(("R", "G", "B")):
                series.append((f"{label[n][:14]} {cname}", centres, h[region][ch] / tot,
                               _CHANNEL_COLOURS[n][ch]))
        if series:
            colour_charts.append(line_chart(f"colour histogram: {region}", series, "8-bit value",
                                            "fraction", xlim=(0.0, 256.0)))
    if colour_charts:
        written.append(atomic_write_bytes(out / "colour_histograms.png", png_bytes(grid(colour_charts, 3))))
    text = _summary_text(sets, label, gaps)
    report["plots"] = sorted(p.name for p in written)
    atomic_write_json(out / "stats.json", _clean(report))
    atomic_write_text(out / "summary.txt", text + "\n")
    return text + f"\nreport: {report_as or out}/stats.json, summary.txt, {len(written)} PNG plots"


def _relative(a, b):
    """(a - b) / |b|: A's figure relative to the reference B (None when undefined)."""
    return None if a is None or b is None or b == 0 else (a - b) / abs(b)


def _get(s: dict, k: str):
    d = s["distributions"].get(k)
    return None if d is None else {"mean": d["mean"], "median": d["median"], "sd": d["sd"]}


def _fraction_differences(sa: dict, sb: dict) -> list[dict]:
    out = []
    for k in ("difficult_fraction", "truncated_fraction"):
        if sa.get(k) is not None and sb.get(k) is not None:
            out.append({"name": k, "a": sa[k], "b": sb[k], "difference": sb[k] - sa[k]})
    for c in sorted(set(sa["class_shares"]) | set(sb["class_shares"])):
        a, b = sa["class_shares"].get(c, 0.0), sb["class_shares"].get(c, 0.0)
        out.append({"name": f"class_share:{c}", "a": a, "b": b, "difference": b - a})
    out.sort(key=lambda d: -abs(d["difference"]))
    return out


def _summary_text(sets, label, gaps) -> str:
    lines = []
    for n, s, _, _ in sets:
        d = s["distributions"]
        lines.append(f"{label[n]}: {s['images']} images ({s['layout']}), {s['objects']} objects, "
                     f"classes {s['classes'] or '-'}")
        vc = s["vehicle_contrast_median"]
        lines.append(
            f"  gray mean {_fmt((d.get('image_gray_mean') or {}).get('median'))}, gray sd "
            f"{_fmt((d.get('image_gray_sd') or {}).get('median'))} (medians over images), vehicle "
            f"contrast {_fmt(vc)} (median; |contrast| {_fmt(s['vehicle_abs_contrast_median'])}, "
            f"brighter than the ring {_fmt(s['vehicle_brighter_fraction'])}), difficult "
            f"{_fmt(s['difficult_fraction'])}, truncated {_fmt(s['truncated_fraction'])}")
    if gaps:
        lines.append("")
        lines.append(f"domain gap, largest first ({label['A']} vs {label['B']}):")
        head = f"{'distribution':<34} {'KS':>6} {'Wasserstein':>12} {'median A':>10} {'median B':>10}"
        lines += [head, "-" * len(head)]
        for g in gaps[:20]:
            lines.append(f"{g['name'][:34]:<34} {g['ks']:>6.3f} {g['wasserstein']:>12.4g} "
                         f"{_fmt(g['median_a']):>10} {_fmt(g['median_b']):>10}")
        if len(gaps) > 20:
            lines.append(f"... {len(gaps) - 20} more in stats.json")
    return "\n".join(lines)
