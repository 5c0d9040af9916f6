"""Scenes: labelled triangle meshes in a z-up metric world frame.

Public API (imported lazily; ``import aerial_synth.scene`` loads no open3d, trimesh or
shapely)::

    load_scene(name_or_path, labels=None, seed=None) -> Scene
    list_scenes() -> list[str]
    export_glb(scene, path) -> Path
    render_map(scene, m_per_px=0.5, rayscene=None) -> MapView
    Scene, SceneObject, LabelConfig, RayScene
"""

from __future__ import annotations

from ..lazy import lazy_module_attrs

__all__ = [
    "load_scene",
    "list_scenes",
    "export_glb",
    "render_map",
    "MapView",
    "Scene",
    "SceneObject",
    "SceneTruth",
    "RoadTruth",
    "LabelConfig",
    "RayScene",
    "LABELS",
]

_LAZY = {
    "load_scene": "io",
    "list_scenes": "io",
    "export_glb": "io",
    "render_map": "mapview",
    "MapView": "mapview",
    "Scene": "model",
    "SceneObject": "model",
    "SceneTruth": "model",
    "RoadTruth": "model",
    "LabelConfig": "model",
    "LABELS": "model",
    "RayScene": "raycast",
}


__getattr__, __dir__ = lazy_module_attrs(__name__, _LAZY, __all__)
