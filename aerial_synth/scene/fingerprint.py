"""A scene's fingerprint that holds across machines: what :meth:`Scene.vertex_hash` pins
exactly, within tolerances a CPU cannot move.

Two machines with the same locked versions may still disagree in the last bits of a
coordinate: OpenBLAS picks its kernels by CPU (``ddot`` on an AVX-512 CPU rounds some dot
products differently from the Haswell/Zen kernel) and glibc's ``sin``/``cos``/``exp`` have
FMA variants. The generators avoid those calls where they decide geometry and snap their
output to a grid (:data:`aerial_synth.scene.build.GRID_M`), so the exact hash normally agrees
too; the fingerprint is the cross-machine check that does not depend on it.

Per object: name, label, material, vertex and face counts (exact: a triangulation flip keeps
them), bounds (to 1 mm) and surface area (to 1 cm², unchanged by a diagonal flip); per label:
area; and the SHA-256 of the label layout traced straight down at 0.5 m. A last-bit or
triangulation difference moves none of these; a moved house, a lost yard object, a changed
outline of 1 mm or a relabelled surface moves at least one.
"""

from __future__ import annotations

import hashlib
import math

import numpy as np

from .model import Scene

__all__ = ["BOUNDS_TOL_M", "AREA_TOL_M2", "RASTER_M", "scene_fingerprint", "compare_fingerprints"]

#: tolerance on every bound of an object (metres)
BOUNDS_TOL_M = 1e-3
#: tolerance on the area of an object or of a label (square metres)
AREA_TOL_M2 = 1e-4
#: cell of the label layout (metres); its cell centres sit off round coordinates (see below)
RASTER_M = 0.5
#: the raster's origin lies this far inside the scene's rounded bounds, so that cell centres
#: do not fall on the round coordinates that drawn edges tend to have
_RASTER_OFFSET_M = 0.137


def _area(v: np.ndarray, f: np.ndarray) -> float:
    if len(f) == 0:
        return 0.0
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    cr = np.cross(b - a, c - a)
    return float(0.5 * np.sqrt((cr * cr).sum(axis=1)).sum())


def scene_fingerprint(scene: Scene, raster: bool = True) -> dict:
    """A JSON-ready dict: ``objects`` (one entry per object, in order), ``label_area_m2``
    and, with ``raster``, ``layout`` (grid and SHA-256 of the 0.5 m label raster)."""
    objs, by_label = [], {}
    for o in scene.objects:
        v = np.asarray(o.vertices, np.float64)
        lo = v.min(axis=0) if len(v) else np.zeros(3)
        hi = v.max(axis=0) if len(v) else np.zeros(3)
        area = _area(v, np.asarray(o.faces))
        by_label[o.label] = by_label.get(o.label, 0.0) + area
        objs.append({"name": o.name, "label": o.label, "material": o.material,
                     "n_vertices": int(len(v)), "n_faces": int(len(o.faces)),
                     "bounds": [round(float(x), 6) for x in (*lo, *hi)],
                     "area_m2": round(area, 6)})
    out = {"objects": objs, "label_area_m2": {k: round(a, 6) for k, a in sorted(by_label.items())}}
    if raster:
        out["layout"] = _layout(scene)
    return out


def _layout(scene: Scene) -> dict:
    from .raycast import RayScene  # lazy: Open3D and numba

    b = scene.bounds()
    x0 = math.floor(float(b[0, 0])) + _RASTER_OFFSET_M
    y1 = math.ceil(float(b[1, 1])) - _RASTER_OFFSET_M
    w = int((float(b[1, 0]) - x0) // RASTER_M)
    h = int((y1 - float(b[0, 1])) // RASTER_M)
    labels, _ = RayScene(scene, nthreads=1).trace_grid((x0, y1), RASTER_M, w, h, ignore=())
    labels = np.ascontiguousarray(labels, np.int16)
    ids, counts = np.unique(labels, return_counts=True)
    return {"origin": [round(x0, 6), round(y1, 6)], "m_per_px": RASTER_M, "size": [w, h],
            "cells_per_label_id": {str(int(i)): int(c) for i, c in zip(ids, counts)},
            "sha256": hashlib.sha256(labels.tobytes()).hexdigest()}


def compare_fingerprints(got: dict, want: dict) -> list[str]:
    """Lines naming every difference beyond the tolerances (empty: the same scene)."""
    out = []
    go, wo = got["objects"], want["objects"]
    if [o["name"] for o in go] != [o["name"] for o in wo]:
        return [f"object names differ: got {len(go)} objects, expected {len(wo)}; first "
                f"difference at {_first_diff([o['name'] for o in go], [o['name'] for o in wo])}"]
    for g, w in zip(go, wo):
        for k in ("label", "material", "n_vertices", "n_faces"):
            if g[k] != w[k]:
                out.append(f"{g['name']}: {k} {g[k]!r}, expected {w[k]!r}")
        d = max(abs(a - b) for a, b in zip(g["bounds"], w["bounds"]))
        if d > BOUNDS_TOL_M:
            out.append(f"{g['name']}: bounds {g['bounds']} differ from {w['bounds']} by {d:.6f} m")
        if abs(g["area_m2"] - w["area_m2"]) > AREA_TOL_M2:
            out.append(f"{g['name']}: area {g['area_m2']} m², expected {w['area_m2']}")
    ga, wa = got["label_area_m2"], want["label_area_m2"]
    for k in sorted(set(ga) | set(wa)):
        if abs(ga.get(k, 0.0) - wa.get(k, 0.0)) > AREA_TOL_M2:
            out.append(f"label {k}: area {ga.get(k)} m², expected {wa.get(k)}")
    if "layout" in got and "layout" in want and got["layout"] != want["layout"]:
        out.append(f"label layout at {RASTER_M} m differs: {got['layout']} vs {want['layout']}")
    return out


def _first_diff(a: list, b: list) -> str:
    for i, (x, y) in enumerate(zip(a, b)):
        if x != y:
            return f"index {i}: {x!r} vs {y!r}"
    return f"index {min(len(a), len(b))}"
