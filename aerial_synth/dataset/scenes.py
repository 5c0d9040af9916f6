"""The scenes of an export, loaded once per process: :func:`load_export_scene` (a Scene with
the export's distractors, or a tiled export's TiledWorld), keyed by what loads them."""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from ..scene import load_scene
from .config import ExportConfig

__all__ = ["DEFAULT_GEOREFERENCE", "load_export_scene", "scene_distractors", "scene_georeference"]

DEFAULT_GEOREFERENCE = {"origin": [0.0, 0.0, 0.0], "crs": None}

_SCENES: OrderedDict = OrderedDict()  # scene key -> Scene or TiledWorld, this process
_DISTRACTORS: dict = {}  # scene key -> the drawn distractors (dicts) of the scene loaded
_MAX_SCENES = 12


def _scene_key(cfg: ExportConfig) -> tuple:
    return (cfg.scene, cfg.labels, cfg.scene_seed, cfg.bbox, cfg.crs, cfg.distractors,
            cfg.seed if cfg.distractors else None, cfg.tile_m is not None)


def load_export_scene(cfg: ExportConfig, keep=None, fresh: bool = False):
    """The scene of the (plain or tiled) export ``cfg`` with its distractors (drawn once per
    dataset from ``SeedSequence([seed, DISTRACTOR_KEY])``, so every process builds the same
    scene); a tiled export (``cfg.tile_m``) gets its TiledWorld. Loaded once per process
    (the last few are kept); ``keep``: an already loaded one to keep for ``cfg``; ``fresh``:
    load it again (the memo left as it is)."""
    if fresh:
        return _load(cfg)
    key = _scene_key(cfg)
    if keep is not None:
        _SCENES[key] = keep
    scene = _SCENES.get(key)
    if scene is None:
        scene = _load(cfg)
        _SCENES[key] = scene
        while len(_SCENES) > _MAX_SCENES:
            _SCENES.popitem(last=False)
    _SCENES.move_to_end(key)
    return scene


def scene_distractors(cfg: ExportConfig) -> list:
    """The distractors drawn into the scene of ``cfg`` (loaded by :func:`load_export_scene`)."""
    load_export_scene(cfg)
    return list(_DISTRACTORS.get(_scene_key(cfg), []))


def _load(cfg: ExportConfig):
    if cfg.tile_m is not None:
        from .tiled import load_world

        return load_world(cfg)
    scene = load_scene(cfg.scene, labels=cfg.labels, seed=cfg.scene_seed, bbox=cfg.bbox, crs=cfg.crs)
    if cfg.distractors:
        from ..render.distractors import DISTRACTOR_KEY, add_distractors

        rng = np.random.default_rng(np.random.SeedSequence([cfg.seed, DISTRACTOR_KEY]))
        scene, drawn = add_distractors(scene, rng, per_hectare=cfg.distractors)
        _DISTRACTORS[_scene_key(cfg)] = drawn
    return scene


def scene_georeference(scene) -> dict:
    """A scene's (or tiled world's) georeference, or the local default."""
    geo = getattr(scene, "georeference", None)
    return geo() if callable(geo) else dict(DEFAULT_GEOREFERENCE)
