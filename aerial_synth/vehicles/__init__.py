"""Vehicle assets: the catalog (models, sizes, classes, colours) and their meshes.

>>> from aerial_synth.vehicles import load_catalog, build_mesh
>>> cat = load_catalog()                       # bundled vehicle_assets/catalog.yaml
>>> v = cat.sample(np.random.default_rng(0), 1)[0]
>>> mesh = build_mesh(v.model, v.color)         # vehicle frame: +x forward, z up
>>> verts_world, faces = mesh.to_world(x_m, y_m, z_m, heading_rad)

Importing this package loads numpy and PyYAML only; trimesh is imported when a mesh is
built.
"""

from __future__ import annotations

from ..lazy import lazy_module_attrs
from .catalog import (
    BODY_TYPES,
    CLASSES,
    Catalog,
    VehicleColor,
    VehicleModel,
    VehicleVariant,
    bundled_catalog_path,
    load_catalog,
)

__all__ = [
    "BODY_TYPES",
    "CLASSES",
    "Catalog",
    "VehicleColor",
    "VehicleModel",
    "VehicleVariant",
    "VehicleMesh",
    "build_mesh",
    "bundled_catalog_path",
    "load_catalog",
]


# ``VehicleMesh`` and ``build_mesh`` load the mesh modules on first use: reading the catalog
# (and ``aerial-synth --help``, which imports this package) needs none of them.
__getattr__, __dir__ = lazy_module_attrs(__name__, {"VehicleMesh": "meshes", "build_mesh": "meshes"}, __all__)
