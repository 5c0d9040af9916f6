"""World = scene + placed vehicle meshes: put a Placement's vehicles into a RayScene.

``add_placement(rayscene, placement, catalog=None)`` builds each vehicle's mesh with
:func:`aerial_synth.vehicles.build_mesh` (the catalog's model and colour named by the
placement), moves it to its pose and adds it with its placement id as instance id, so the
renderer's instance buffer carries the ids of ``placement.json``. Meshes are cached per
(model, colour). ``simple_boxes=True`` (or a missing vehicles package) uses two-box stand-ins
(body + glazed cabin) of each vehicle's size instead.
"""

from __future__ import annotations

import numpy as np

from ..scene.model import MATERIAL_IDS

__all__ = ["add_placement", "box_vehicle_mesh"]


def box_vehicle_mesh(length_m: float, width_m: float, height_m: float, rgb=(0.7, 0.7, 0.7)):
    """A two-box stand-in vehicle in the vehicle frame (+x forward, z up, origin footprint
    centre on the ground): a body and a glazed cabin, slightly rearward.

    Returns (vertices (n, 3), faces (m, 3), face_material (m,) uint8, face_albedo (m, 3)).
    """
    import trimesh

    body_h = 0.55 * height_m
    b = trimesh.creation.box((length_m, width_m, body_h))
    vb = np.asarray(b.vertices) + [0, 0, body_h / 2]
    fb = np.asarray(b.faces)
    cab_l, cab_w = 0.5 * length_m, 0.86 * width_m
    c = trimesh.creation.box((cab_l, cab_w, height_m - body_h))
    vc = np.asarray(c.vertices) + [-0.05 * length_m, 0, body_h + (height_m - body_h) / 2]
    fc = np.asarray(c.faces) + len(vb)
    nc = np.asarray(c.face_normals)
    v = np.concatenate([vb, vc])
    f = np.concatenate([fb, fc])
    mat = np.full(len(f), MATERIAL_IDS["paint"], np.uint8)
    cab_mat = np.where(nc[:, 2] > 0.5, MATERIAL_IDS["paint"], MATERIAL_IDS["glass"])
    mat[len(fb) :] = cab_mat
    alb = np.tile(np.asarray(rgb, np.float32), (len(f), 1))
    alb[mat == MATERIAL_IDS["glass"]] = (0.05, 0.07, 0.09)
    return v, f, mat, alb


def _to_world(v: np.ndarray, x: float, y: float, z: float, heading: float) -> np.ndarray:
    c, s = np.cos(heading), np.sin(heading)
    out = np.empty_like(v, dtype=np.float64)
    out[:, 0] = x + c * v[:, 0] - s * v[:, 1]
    out[:, 1] = y + s * v[:, 0] + c * v[:, 1]
    out[:, 2] = z + v[:, 2]
    return out


def add_placement(rayscene, placement, catalog=None, simple_boxes: bool = False) -> list[int]:
    """Add every vehicle of ``placement`` to ``rayscene`` (ids = placement ids).

    catalog : a vehicles Catalog; None = the bundled catalog.
    Returns the ids added. Unknown model or colour names raise the catalog's AssetError.
    """
    build = None
    if not simple_boxes:
        try:
            # lazy: the catalog meshes need trimesh; simple boxes do without
            from ..vehicles import build_mesh, load_catalog  # noqa: F401

            build = build_mesh
            if catalog is None:
                catalog = load_catalog()
        except ImportError:
            build = None
    cache: dict = {}
    ids = []
    for pv in placement.vehicles:
        if build is None:
            key = ("box", round(pv.length_m, 4), round(pv.width_m, 4), round(pv.height_m, 4))
            if key not in cache:
                cache[key] = box_vehicle_mesh(pv.length_m, pv.width_m, pv.height_m)
            v, f, mat, alb = cache[key]
            vw = _to_world(v, pv.x_m, pv.y_m, pv.z_m, pv.heading_rad)
        else:
            key = (pv.model, pv.color)
            if key not in cache:
                cache[key] = build(catalog.model(pv.model), catalog.color(pv.color))
            mesh = cache[key]
            vw, f = mesh.to_world(pv.x_m, pv.y_m, pv.z_m, pv.heading_rad)
            mat, alb = mesh.face_material, mesh.face_albedo
        rayscene.add_vehicle(pv.id, vw, f, mat, alb)
        ids.append(int(pv.id))
    return ids
