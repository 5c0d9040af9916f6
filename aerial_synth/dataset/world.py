"""What one render task of a tiled world needs: the tiles its camera sees, with vehicles.

Moved out of :mod:`aerial_synth.scene.tiles`, which must not reach up into ``render``
(the package order is written in ``tests/foundation/test_imports.py``).
"""

from __future__ import annotations

import dataclasses

from ..render import add_placement
from ..scene.raycast import RayScene
from ..scene.tiles import TiledWorld, TileGrid

__all__ = ["world_for_camera"]


def world_for_camera(world: TiledWorld, grid: TileGrid, placement, camera, ground_z: float = 0.0,
                     pad_m: float = 30.0, catalog=None, simple_boxes: bool = False):
    """What one render task needs and nothing more: the RayScene of the tiles the camera's
    ground footprint touches (see :meth:`TiledWorld.scene_for_xy`) holding the placement's
    vehicles that stand in that window.

    Returns (rayscene, placement of those vehicles, tiles). The vehicles keep their ids, so
    the frame's instance buffer carries the ids of the whole world's placement."""
    fp = camera.ground_footprint_xy(ground_z)
    scene, tiles = world.scene_for_xy(grid, fp, pad_m)
    b = scene.bounds()
    lo, hi = b[0, :2], b[1, :2]
    vs = [v for v in placement.vehicles
          if lo[0] - v.length_m <= v.x_m <= hi[0] + v.length_m and lo[1] - v.length_m <= v.y_m <= hi[1] + v.length_m]
    sub = dataclasses.replace(placement, vehicles=vs)
    rs = RayScene(scene)
    add_placement(rs, sub, catalog, simple_boxes=simple_boxes)
    return rs, sub, tiles
