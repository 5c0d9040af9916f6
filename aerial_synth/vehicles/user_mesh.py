"""User vehicle meshes (glTF/GLB/OBJ): read a file and bring it into the vehicle frame.

trimesh is imported only when a file is read.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import AssetError
from .model import AXES

__all__ = ["UserPart", "axes_rotation", "load_user_mesh_parts"]


@dataclass(frozen=True, eq=False)
class UserPart:
    """One geometry of a user mesh after the change to the vehicle frame.

    material_name : the file's material name ('' if none)
    material      : aerial-synth material guessed from the name (paint, glass, tyre, ...)
    rgb           : the file's base colour, RGB in [0, 1]
    vertices      : (n, 3) float64, metres, vehicle frame; faces : (m, 3) int64
    """

    name: str
    material_name: str
    material: str
    rgb: tuple[float, float, float]
    vertices: np.ndarray
    faces: np.ndarray


def axes_rotation(forward: str, up: str) -> np.ndarray:
    """(3, 3) rotation taking the file's ``forward`` axis to +x and ``up`` to +z.

    Rows are the file-frame directions of vehicle +x (forward), +y (left = up x forward)
    and +z (up); apply as ``v_vehicle = v_file @ R.T``. det(R) = +1, so winding is kept.
    """
    f = np.asarray(AXES[forward], float)
    u = np.asarray(AXES[up], float)
    return np.stack([f, np.cross(u, f), u])


def _guess_material(name: str) -> str:
    n = name.lower()
    if any(k in n for k in ("glass", "window", "windscreen", "windshield")):
        return "glass"
    if any(k in n for k in ("tyre", "tire", "wheel", "rubber")):
        return "tyre"
    if any(k in n for k in ("tail", "brake", "rear_light", "rearlight")):
        return "light_rear"
    if any(k in n for k in ("light", "lamp")):
        return "light_front"
    if any(k in n for k in ("chrome", "metal", "rim")):
        return "metal"
    if any(k in n for k in ("trim", "plastic", "bumper", "black")):
        return "trim"
    return "paint"


def _visual_rgb(mesh) -> tuple[float, float, float]:
    vis = getattr(mesh, "visual", None)
    try:
        mat = getattr(vis, "material", None)
        if mat is not None:
            c = np.asarray(mat.main_color, float)[:3] / 255.0
            return tuple(float(x) for x in np.clip(c, 0, 1))
        fc = getattr(vis, "face_colors", None)
        if fc is not None and len(fc):
            c = np.asarray(fc, float)[:, :3].mean(axis=0) / 255.0
            return tuple(float(x) for x in np.clip(c, 0, 1))
    except Exception:  # noqa: BLE001 - odd visuals fall back to grey
        pass
    return (0.5, 0.5, 0.5)


@lru_cache(maxsize=64)
def _load_user_mesh_cached(path: Path, mtime_ns: int, scale: float, forward: str, up: str):
    import trimesh

    try:
        loaded = trimesh.load(str(path), force="scene", process=False)
    except Exception as exc:  # noqa: BLE001 - any loader failure is a bad asset
        msg = " ".join(str(exc).split())[:200]
        raise AssetError(f"cannot read mesh {path.name!r}: {type(exc).__name__}: {msg}") from None
    meshes = [g for g in loaded.dump(concatenate=False) if isinstance(g, trimesh.Trimesh)]
    meshes = [m for m in meshes if len(m.faces)]
    if not meshes:
        raise AssetError(f"mesh {path.name!r} holds no triangles")
    rot = axes_rotation(forward, up)
    raw = []
    for k, m in enumerate(meshes):
        mat = getattr(getattr(m, "visual", None), "material", None)
        mname = str(getattr(mat, "name", "") or "") if mat is not None else ""
        v = np.asarray(m.vertices, np.float64) * scale @ rot.T
        gname = str(m.metadata.get("name", "") or f"part{k}")
        raw.append((gname, mname, v, np.asarray(m.faces, np.int64), _visual_rgb(m)))
    allv = np.concatenate([r[2] for r in raw])
    lo, hi = allv.min(axis=0), allv.max(axis=0)
    shift = np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    out = []
    for gname, mname, v, f, rgb in raw:
        vv = v - shift
        vv.setflags(write=False)
        f.setflags(write=False)
        out.append(UserPart(gname, mname, _guess_material(mname or gname), rgb, vv, f))
    return tuple(out)


def load_user_mesh_parts(path: Path, scale: float = 1.0, forward: str = "+x",
                         up: str = "+z") -> tuple[UserPart, ...]:
    """Read a glTF/GLB/OBJ file and bring it into the vehicle frame: multiply by ``scale``,
    rotate ``forward`` to +x and ``up`` to +z, centre the footprint on the origin and stand
    it on z = 0. Vertices and faces are kept as in the file otherwise (no merging or
    re-ordering). Raises :class:`AssetError` when the file cannot be read."""
    path = Path(path)
    if not path.is_file():
        raise AssetError(f"mesh file not found: {path}")
    return _load_user_mesh_cached(path, path.stat().st_mtime_ns, float(scale), forward, up)
