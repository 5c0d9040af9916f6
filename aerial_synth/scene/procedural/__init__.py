"""Seeded procedural scenes: roads, markings, sidewalks, buildings, trees, poles, water.

A scene spec is a YAML mapping (see ``scenes/*.yaml`` and ``docs/scenes.md``) holding the
seed, the size and every generator parameter. :func:`generate` turns a spec mapping into a
:class:`~aerial_synth.scene.model.Scene`; the same spec and seed always give the same
vertices (checked with :meth:`Scene.vertex_hash`).

World frame: metres, x east, y north, z up; the scene is centred on the origin.
Heights: ground 0.0, road and parking 0.05, lane markings 0.06, sidewalks raised 0.12.
Ground covers the scene except water (holes only there, the one other surface at its
height), so it lies 5 cm under roads and parking and catches every camera ray that slips
past their edges; no two surfaces share a height over the same point.

The generator also fills ``Scene.truth`` (road polygons and centre lines) for tests and the
validator; placement never reads it.
"""


from __future__ import annotations

import dataclasses
from typing import Mapping

import numpy as np

from ...errors import SceneError
from ..build import snap_to_grid
from ..model import Scene
from .builder import Z_GROUND, Z_MARKING, Z_ROAD, Z_SIDEWALK, Builder
from .city import with_size_m
from .generators import REGISTRY as GENERATORS
from .spec import check_spec

__all__ = ["generate", "checked_spec", "GENERATORS", "Z_GROUND", "Z_ROAD", "Z_MARKING", "Z_SIDEWALK"]

# GENERATORS: the generator registry (generators.py); adding a generator is one module with
# a ``GENERATOR`` plus one line in generators.BUILTIN.


def checked_spec(spec: Mapping, where: str, seed: int | None = None) -> tuple[dict, int]:
    """``(normalised spec, seed)`` as :func:`generate` sees it (``size_km`` turned into
    ``size_m``, every field checked), without building anything. Raises SceneError."""
    if not isinstance(spec, Mapping):
        raise SceneError(f"{where}: expected a mapping, got {type(spec).__name__}")
    return check_spec(with_size_m(spec, where), where, GENERATORS.names(), seed)


def generate(spec: Mapping, seed: int | None = None, source: str = "") -> Scene:
    """Build a procedural scene from a spec mapping.

    spec : mapping with ``generator`` (one of :data:`GENERATORS`: city_park | suburb |
           highway | city | depot), ``name``, ``seed``,
           ``size_m`` [w, h] and the generator's parameters (see docs/scenes.md)
    seed : overrides ``spec["seed"]`` when given (0 is a valid seed)
    source : provenance string stored in ``Scene.source``
    """
    where = source or "scene spec"
    if not isinstance(spec, Mapping):
        raise SceneError(f"{where}: expected a mapping, got {type(spec).__name__}")
    kind = spec.get("generator")
    spec, s = checked_spec(spec, where, seed)
    size = spec["size_m"]
    from shapely.errors import ShapelyError

    rng = np.random.default_rng(s)
    name = str(spec.get("name", kind))
    b = Builder(name, spec, rng)
    meta = {"generator": kind, "seed": s, "size_m": [float(v) for v in size]}
    try:
        GENERATORS.get(kind).build(b, spec)
        if not b.roads:
            raise SceneError(f"{where}: the spec produced no road")
        sc = b.scene(source or f"procedural:{name}", meta)
        # one seed, one scene on every CPU: x and y on the grid of build.GRID_M (heights keep
        # their designed values: road 0.05 m, markings 0.06 m, ...)
        sc.objects = [dataclasses.replace(o, vertices=np.column_stack(
            [snap_to_grid(o.vertices[:, :2]), o.vertices[:, 2]])) for o in sc.objects]
        return sc
    except SceneError as exc:
        if where in str(exc):
            raise
        raise SceneError(f"{where}: {exc}") from None
    except (KeyError, TypeError, ValueError, IndexError, ZeroDivisionError, AttributeError,
            NotImplementedError, ShapelyError) as exc:
        # the fields are valid one by one, but together they give impossible geometry
        msg = " ".join(str(exc).split())[:200]
        raise SceneError(
            f"{where}: the {kind} generator cannot build this spec ({type(exc).__name__}: {msg})"
        ) from None
