"""The export plan: everything :func:`~aerial_synth.dataset.sample.render_sample` needs to make
image ``i``, built and checked once from an :class:`~aerial_synth.dataset.config.ExportConfig`.

An :class:`ExportPlan` is a value (frozen, hashable, picklable): it holds no loaded scene and
no state. It says

- where each placement group's scene comes from (:class:`SceneSource`: one scene, a
  ``--scene-mix`` or a tiled world, with :meth:`SceneSource.entry_for_group`);
- how image ``i``'s camera is drawn (:class:`CameraPlan`: fixed, or a GSD or altitude
  range, with :meth:`CameraPlan.camera_for`);
- the render options (:class:`~aerial_synth.render.config.RenderConfig`) and the box
  options (:class:`~aerial_synth.annotate.boxes.BoxConfig`).

Seed streams (the export's, kept for every consumer: export, stream, ``render``): image
``i`` draws its camera and rendering from ``SeedSequence([seed, i])`` (spawned in two);
placement group ``g = i // images_per_placement`` draws its placement from
``SeedSequence([seed, g, PLACEMENT_STREAM])``; a range draws image ``i``'s GSD from
``SeedSequence([seed, i, GSD_STREAM])``; a mix draws group ``g``'s entry from
``SeedSequence([seed, g, MIX_STREAM])``.
"""

from __future__ import annotations

import dataclasses
import functools
from dataclasses import dataclass

import numpy as np

from ..annotate.boxes import BoxConfig
from ..camera import CameraConfig, grid_poses, sample_pose_targeted
from ..render.config import RenderConfig
from .config import ExportConfig
from .gsd import GSD_STREAM, GsdRange, scene_cap_m
from .scene_mix import parse_mix
from .scenes import load_export_scene

__all__ = ["CameraPlan", "ExportPlan", "GroupEntry", "SceneSource", "build_plan"]


@dataclass(frozen=True)
class GroupEntry:
    """What placement group ``group`` renders: the scene (name or file), the scenario, and
    for a mix the drawn entry (``mix``: {"entry", "scene", "scenario"}, else None)."""

    group: int
    scene: str
    scenario: str
    mix: dict | None = None


@dataclass(frozen=True)
class SceneSource:
    """Where the placement groups' scenes come from.

    kind  : "plain" (one scene), "mix" (``--scene-mix``: each group draws an entry) or
            "tiled" (``--tile-m``: one world, each group a window of tiles)
    cfg   : the export's parameters (scene, labels, seed, distractors, mix, tiles)
    """

    kind: str
    cfg: ExportConfig

    @classmethod
    def of(cls, cfg: ExportConfig) -> "SceneSource":
        if cfg.tile_m is not None:
            return cls("tiled", cfg)
        return cls("mix" if cfg.scene_mix is not None else "plain", cfg)

    @functools.cached_property
    def mix(self):
        """The parsed :class:`~aerial_synth.dataset.scene_mix.SceneMix` (kind "mix")."""
        return parse_mix(self.cfg.scene_mix) if self.kind == "mix" else None

    def entry_for_group(self, group: int) -> GroupEntry:
        """Group ``group``'s scene and scenario (a mix draws them; cheap, nothing loaded)."""
        cfg = self.cfg
        if self.kind != "mix":
            return GroupEntry(int(group), cfg.scene, cfg.scenario)
        mix = self.mix
        k = mix.index_for_group(cfg.seed, group)
        entry = mix.entries[k]
        scenario = mix.scenario_of(entry, cfg.scenario)
        return GroupEntry(int(group), entry.scene, scenario,
                          {"entry": k, "scene": entry.scene, "scenario": scenario})

    def scene_config(self, group: int) -> ExportConfig:
        """The parameters group ``group``'s scene is loaded with (a mix's entry as a plain
        export's): what :func:`~aerial_synth.dataset.scenes.load_export_scene` takes."""
        if self.kind != "mix":
            return self.cfg
        return dataclasses.replace(self.cfg, scene=self.entry_for_group(group).scene, scene_mix=None)

    def scene_for_group(self, group: int):
        """Group ``group``'s scene, loaded through this process's scene memo
        (:func:`~aerial_synth.dataset.scenes.load_export_scene`): a Scene, or the
        TiledWorld of a tiled export."""
        return load_export_scene(self.scene_config(group))


@dataclass(frozen=True)
class CameraPlan:
    """How image ``i``'s camera is drawn.

    kind   : "fixed" (``camera`` for every image), "gsd" or "altitude" (a range: each image
             draws its nadir GSD, the lens fixed; :mod:`aerial_synth.dataset.gsd`), or "grid"
             (survey tiles over the bounds, image ``i`` the ``i % n``-th: ``render --sampler grid``)
    seed   : the dataset seed
    camera : the fixed camera, or the range's base camera (size, tilt, altitude or GSD)
    range  : the range's lens and GSD bounds (None when fixed)
    overlap, ground_z : a grid's tile overlap and ground height (:func:`~aerial_synth.camera.grid_poses`)
    """

    kind: str
    seed: int
    camera: CameraConfig
    range: GsdRange | None = None
    overlap: float = 0.2
    ground_z: float = 0.0

    @classmethod
    def of(cls, cfg: ExportConfig) -> "CameraPlan":
        r = GsdRange.of(cfg)
        if r is None:
            return cls("fixed", cfg.seed, cfg.camera_config())
        return cls("gsd" if cfg.gsd_range is not None else "altitude", cfg.seed, cfg.camera, r)

    @property
    def widest(self) -> CameraConfig:
        """The camera every image fits in (a range's highest GSD)."""
        return self.camera if self.range is None else self.range.camera_config(self, self.range.gsd_hi_m)

    def config_for(self, index: int, bounds=None) -> CameraConfig:
        """Image ``index``'s CameraConfig; a range's GSD is drawn from
        ``SeedSequence([seed, index, GSD_STREAM])`` over the part of the range whose frames
        fit in ``bounds`` ([[xmin, ymin], [xmax, ymax]], :func:`~.gsd.scene_cap_m`)."""
        if self.range is None:
            return self.camera
        rng = np.random.default_rng(np.random.SeedSequence([self.seed, int(index), GSD_STREAM]))
        return self.range.camera_config(self, self.range.draw(rng, scene_cap_m(self, bounds)))

    def camera_for(self, index: int, bounds, placement, clear=None):
        """Image ``index``'s camera, aimed near a vehicle of ``placement`` with its footprint
        inside ``bounds``: the first of ``SeedSequence([seed, index])``'s two streams (the
        second draws the rendering). ``clear(cam)`` False redraws a pose (a camera inside a
        building)."""
        if self.kind == "grid":
            poses = self.grid(bounds)
            return poses[int(index) % len(poses)]
        cam_ss, _ = np.random.SeedSequence([self.seed, int(index)]).spawn(2)
        return sample_pose_targeted(self.config_for(index, bounds), placement, np.random.default_rng(cam_ss),
                                    within_xy=bounds, clear=clear)


    def grid(self, bounds) -> list:
        """A grid plan's poses over ``bounds`` (raises CameraError when there are none)."""
        return _grid_poses(self.camera, tuple(np.asarray(bounds, np.float64)[:, :2].ravel().tolist()),
                           self.overlap, self.ground_z)


@functools.lru_cache(maxsize=8)
def _grid_poses(camera: CameraConfig, bounds: tuple, overlap: float, ground_z: float) -> list:
    return grid_poses(camera, np.array(bounds).reshape(2, 2), overlap=overlap, ground_z=ground_z)


@dataclass(frozen=True)
class ExportPlan:
    """Everything that makes image ``i`` (see the module's text). Build it with
    :func:`build_plan`; ``cfg`` stays the source of the metadata's parameters (names,
    splits, seeds)."""

    cfg: ExportConfig
    scenes: SceneSource
    camera: CameraPlan
    render: RenderConfig
    box: BoxConfig

    @property
    def images(self) -> int:
        return self.cfg.images

    def group_of(self, index: int) -> int:
        """The placement group of image ``index``."""
        return int(index) // self.cfg.images_per_placement

    def group_indices(self, group: int) -> range:
        """The images of placement group ``group`` (all of them, up to ``cfg.images``)."""
        first = int(group) * self.cfg.images_per_placement
        return range(first, min(first + self.cfg.images_per_placement, self.cfg.images))


def build_plan(cfg: ExportConfig, render: RenderConfig | None = None,
               camera: CameraPlan | None = None) -> ExportPlan:
    """The plan of the export ``cfg`` (checked as ``ExportConfig`` checks it; the mix is
    parsed here once). ``render`` / ``camera`` replace the config's own (the ``render``
    command's backend and lens options, which an export does not take)."""
    if not isinstance(cfg, ExportConfig):
        raise TypeError(f"build_plan: expected an ExportConfig, got {type(cfg).__name__}")
    scenes = SceneSource.of(cfg)
    if scenes.kind == "mix":
        scenes.mix  # noqa: B018 -- parsed (and checked) once, here
    return ExportPlan(cfg, scenes, camera if camera is not None else CameraPlan.of(cfg),
                      render if render is not None else cfg.render.config(), cfg.box)
